"""The warm-start policy of ``M(Λ)``: which equilibria a forward solve at a new Λ starts from.

``M(Λ)`` itself (:class:`~breastcore.inverse.operator.MeasurementModel`) keeps no state:
whoever runs a sequence of solves (an identification, a finite difference, a sensitivity
re-identification) owns a :class:`WarmStarts` and passes it in, so what a solve starts
from is visible at the call.
"""

from __future__ import annotations

import numpy as np


class WarmStarts:
    """The last remembered equilibria, used as warm starts for solves within ``radius`` of them.

    Parameters
    ----------
    radius : float
        Warm-start only where ``max_j |Λ_j / Λ⁰_j − 1| ≤ radius`` (Λ⁰ the remembered Λ);
        farther, and with nothing remembered, the solve is cold (unless ``tangent_starts``
        applies). 0: warm starts only at the same Λ, and no tangent starts. (The standing posture has more than one local equilibrium: a
        warm start from far away can land on another branch than the cold path that
        defines ``M(Λ)``.)
    snapshots : int
        Keep the last this many remembered equilibria in ``history`` (0: none), for the
        reduced-space start of solves beyond ``radius``
        (:func:`~breastcore.forward.reduced.reduced_start`).
    tangent_starts : bool
        With ``radius > 0``: once :meth:`remember_tangents` has given the equilibria's
        derivatives ``∂x/∂Λ`` at the remembered Λ⁰, a solve at any Λ starts from the
        first-order predictor ``x⁰ + ∂x/∂Λ (Λ − Λ⁰)`` (a parameter-continuation Euler
        step), within ``radius`` or beyond it. Without them, the starts above.

    Notes
    -----
    The predictor costs nothing extra in an identification with the implicit Jacobian:
    ``∂x/∂Λ_j = −K⁻¹ ∂g/∂Λ_j`` is the intermediate result of each Jacobian
    (:meth:`~breastcore.inverse.operator.MeasurementModel.implicit_jacobian`), and LM's
    trial points are steps from the point where it was taken. The measurement model replaces
    a predictor that inverts a tet by the start without it (``starts(..., predict=False)``).
    """

    def __init__(self, radius: float, snapshots: int = 0, tangent_starts: bool = False):
        self.radius = float(radius)
        self.values = None
        self.positions = {}
        self.snapshots = int(snapshots)
        self.history = []                   # the last ``snapshots`` remembered (Λ, positions), oldest first
        self.tangent_starts = bool(tangent_starts)
        self.tangents = {}                  # {posture name: (N, 3, 6) ∂x/∂Λ} at ``values``, or empty

    @classmethod
    def at(cls, radius, solutions, values) -> "WarmStarts":
        """A policy that starts from ``solutions`` (the equilibria at ``Λ = values``)."""
        warm = cls(radius)
        warm.remember(solutions, values)
        return warm

    def remember(self, solutions, values) -> None:
        """Start the next solves from these equilibria, at ``Λ = values``."""
        values = np.array(values, dtype=float)
        positions = {name: s.position for name, s in solutions.items()}
        same = self.values is not None and np.array_equal(values, self.values) and \
            positions.keys() == self.positions.keys() and all(positions[k] is self.positions[k] for k in positions)
        if not same:
            self.tangents = {}      # they are the derivatives of the old equilibria (another Λ⁰, or another branch)
        self.positions = positions
        self.values = values
        if self.snapshots:
            self.history = (self.history + [(self.values, self.positions)])[-self.snapshots:]

    def remember_tangents(self, values, tangents) -> None:
        """Predict the next starts with ``tangents`` ({posture name: (N, 3, 6) ``∂x/∂Λ``, m per
        parameter unit}), the derivatives of the remembered equilibria at ``values``.

        Ignored unless ``tangent_starts`` and ``radius > 0``, and unless ``values`` is the
        remembered Λ⁰ (the tangents of another point would predict from the wrong state). The
        caller gives the tangents of the remembered equilibria; :meth:`remember` drops them when
        it remembers other equilibria, even at the same Λ (a cold re-solve on another branch).
        """
        if self.tangent_starts and self.radius > 0 and self.values is not None and \
                np.array_equal(np.asarray(values, dtype=float), self.values):
            self.tangents = {name: np.asarray(t, dtype=float) for name, t in tangents.items()}

    def starts(self, values, postures, predict=True) -> dict:
        """``{posture name: (N, 3) start or None}`` for a solve at ``values``; with ``predict=False``,
        the starts without the tangent predictor."""
        if self.values is None:
            return {p.name: None for p in postures}
        step = np.asarray(values, dtype=float) - self.values
        near = np.max(np.abs(step / self.values)) <= self.radius
        out = {}
        for p in postures:
            tangent = self.tangents.get(p.name)
            if predict and tangent is not None and p.name in self.positions:
                out[p.name] = self.positions[p.name] + tangent @ step
            else:
                out[p.name] = self.positions.get(p.name) if near else None
        return out
