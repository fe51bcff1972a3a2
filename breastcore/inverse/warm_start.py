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
        farther, and with nothing remembered, the solve is cold. 0: warm starts only
        at the same Λ. (The standing posture has more than one local equilibrium: a
        warm start from far away can land on another branch than the cold path that
        defines ``M(Λ)``.)
    snapshots : int
        Keep the last this many remembered equilibria in ``history`` (0: none), for the
        reduced-space start of solves beyond ``radius``
        (:func:`~breastcore.forward.reduced.reduced_start`).
    """

    def __init__(self, radius: float, snapshots: int = 0):
        self.radius = float(radius)
        self.values = None
        self.positions = {}
        self.snapshots = int(snapshots)
        self.history = []                   # the last ``snapshots`` remembered (Λ, positions), oldest first

    @classmethod
    def at(cls, radius, solutions, values) -> "WarmStarts":
        """A policy that starts from ``solutions`` (the equilibria at ``Λ = values``)."""
        warm = cls(radius)
        warm.remember(solutions, values)
        return warm

    def remember(self, solutions, values) -> None:
        """Start the next solves from these equilibria, at ``Λ = values``."""
        self.positions = {name: s.position for name, s in solutions.items()}
        self.values = np.array(values, dtype=float)
        if self.snapshots:
            self.history = (self.history + [(self.values, self.positions)])[-self.snapshots:]

    def starts(self, values, postures) -> dict:
        """``{posture name: (N, 3) start or None}`` for a solve at ``values``."""
        near = self.values is not None and \
            np.max(np.abs(np.asarray(values) / self.values - 1.0)) <= self.radius
        return {p.name: self.positions.get(p.name) if near else None for p in postures}
