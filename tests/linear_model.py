"""A stand-in MeasurementModel with a closed-form ``M(Λ)``, for the bookkeeping of identify and sensitivity."""

import numpy as np

TRUTH = np.array([0.0562, 0.05, 1000.0, 150.0, 8000.0, 1600.0])


class _NoForwardModel:
    def after_fork(self):
        pass


class _NoWarmStarts:
    """Its solves need no start; a policy that remembers nothing (no tangent predictor either)."""

    def remember(self, solutions, values):
        pass

    def remember_tangents(self, values, tangents):
        pass


class LinearModel:
    """``M(Λ) = M₀ exp(A ln(Λ/Λ̄))``, whose cold solves read every measurement ``1 + drift`` times higher.

    With a drift it stands in for a mesh whose warm and cold equilibria differ (two branches).
    """

    warm_radius = 0.05
    model = _NoForwardModel()

    def __init__(self, drift=0.0):
        rng = np.random.default_rng(3)
        self.A = rng.normal(size=(15, 6))
        self.M0 = np.linspace(1.0, 2.0, 15)
        self.drift = drift
        self.solves = 0

    def warm_starts(self):
        return _NoWarmStarts()

    def solve(self, values, warm=None, jacobian=False):
        """Without warm starts (``warm`` None) a solve is cold, and reads the cold branch."""
        self.solves += 1
        return {"values": np.array(values, float), "cold": warm is None}

    @staticmethod
    def solved_cold(solutions):
        return solutions["cold"]

    def measure(self, solutions):
        M = self.M0 * np.exp(self.A @ np.log(solutions["values"] / TRUTH))
        return (M * (1 + self.drift if solutions["cold"] else 1.0)).reshape(3, 5)

    def implicit_jacobian(self, values, solutions, tangents=None):
        M = self.measure(solutions).reshape(15)
        return (M[:, None] * self.A / np.asarray(values)[None, :]).reshape(3, 5, 6)
