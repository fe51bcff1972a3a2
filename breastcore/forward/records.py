"""What a forward solve returns: a posture's equilibrium, or the typed error of a failed solve."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from breastcore.model.postures import Posture
from breastcore.model.torso import torso_penetration


class SolveError(RuntimeError):
    """A solve that did not reach its tolerance; carries the diagnostics.

    Attributes
    ----------
    iterations : int
        Newton (or CG) iterations spent in all continuation steps.
    gradient_norm, tolerance : float
        Free-dof gradient norm reached and the one asked for, N.
    min_det_F : float
        Smallest ``det F`` over the tets at the last admissible iterate.
    load_factor, smoothing : float
        Continuation level reached: fraction of gravity and δ (m).
    posture : str
    """

    def __init__(self, message, *, iterations, gradient_norm, tolerance, min_det_F,
                 load_factor, smoothing, posture):
        self.iterations = iterations
        self.gradient_norm = gradient_norm
        self.tolerance = tolerance
        self.min_det_F = min_det_F
        self.load_factor = load_factor
        self.smoothing = smoothing
        self.posture = posture
        self._message = message
        super().__init__(
            f"{posture}: {message} after {iterations} iterations; |g|={gradient_norm:.3e} N "
            f"(tolerance {tolerance:.3e} N), min det F={min_det_F:.3e}, "
            f"continuation reached load factor {load_factor:.4g}, δ={smoothing:.3e} m")

    def __reduce__(self):                                            # picklable (parallel postures)
        return (_rebuild_solve_error, (self._message, dict(
            iterations=self.iterations, gradient_norm=self.gradient_norm, tolerance=self.tolerance,
            min_det_F=self.min_det_F, load_factor=self.load_factor, smoothing=self.smoothing,
            posture=self.posture)))


def _rebuild_solve_error(message, fields):
    return SolveError(message, **fields)


def raise_first_failure(outcomes):
    """``outcomes`` (a list of solutions), or the first :class:`SolveError` among them raised: the
    postures of a parallel solve all run, and return their failures instead of raising them."""
    for outcome in outcomes:
        if isinstance(outcome, SolveError):
            raise outcome
    return outcomes


@dataclass(frozen=True)
class PostureSolution:
    """Equilibrium of one posture. Positions in m, forces in N, energy in J."""

    posture: Posture
    position: np.ndarray
    converged: bool
    iterations: int
    continuation_steps: int
    gradient_norm: float
    tolerance: float
    energy: float
    min_det_F: float
    max_stretch: float
    wall_time: float
    #: Negative eigenvalues of the exact Hessian at ``position`` (None: unknown, no PARDISO).
    negative_pivots: int | None = None
    #: Whether the solve started from the reference state (None: not recorded; see MeasurementModel.solve).
    cold_start: bool | None = None
    #: ``(Λ, rows, ∂x/∂Λ)``: the implicit-Jacobian rows of this posture at Λ, and its (N, 3, 6)
    #: tangent, if a worker computed them.
    jacobian_rows: tuple | None = None

    @property
    def negative_eigenvalues(self) -> int:
        """Negative eigenvalues of the exact Hessian at the returned position (``-1``: unknown, no PARDISO).

        Computed at the solution itself, for Newton and CG solves, cold or warm. Zero
        at a stable equilibrium (a local minimum of ``J_h``); a saddle is left by
        :func:`~breastcore.nonlinear.saddle.escape_saddle` before returning, and > 0 only where
        that escape keeps it (a neutral direction, or a failed last round).
        """
        return -1 if self.negative_pivots is None else int(self.negative_pivots)

    @property
    def torso_penetration(self) -> float:
        """Largest depth of a node behind the torso plane y = 0, m (see breastcore.model.torso)."""
        return torso_penetration(self.position)
