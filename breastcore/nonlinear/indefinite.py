"""Newton steps where the step matrix is indefinite: diagonal shifts, and the PSD projection.

:func:`~breastcore.nonlinear.newton.newton` factorises the exact step matrix first. Where PARDISO's
inertia shows negative pivots it tries ``K + σ |diag K|`` for σ in :data:`INERTIA_SHIFTS` (where
:class:`Shifts` says they may help), then the projection (:func:`projected_step`). Deep in an
indefinite phase (more than :data:`DEEP_INDEFINITE_PIVOTS` negative pivots) the next steps may go to
the projection directly (``deep_skips``).
"""

from __future__ import annotations

from breastcore.linalg.factorization import factor_solve, shift_diagonal
from breastcore.nonlinear.line_search import _line_search, descends


#: Relative diagonal shifts ``σ`` tried, in order, by ``inertia_shift`` steps: ``K + σ |diag K|``.
INERTIA_SHIFTS = (1e-2, 1e-1)
#: ``skip_futile_shifts``: no shift is tried where the step matrix has more negative pivots than
#: this. In the cold ultra-thin standing and bent45 solves 30 % off Λ̄, the shifts of
#: :data:`INERTIA_SHIFTS` made the step matrix positive definite at 1-6 negative pivots and at none
#: of 8-78 (docs/benchmarks.md, "Inexact Newton steps").
MAX_SHIFT_PIVOTS = 7
#: ``deep_skips``: an exact factorisation with more than this many negative pivots starts a deep
#: indefinite phase. Such counts fall over several iterations (cold fine50k standing: 238, 50, 48,
#: 43, …, 17, 13, 10, 9, 8 over 16 iterations), so the next steps would be projected whatever their
#: exact factor said.
DEEP_INDEFINITE_PIVOTS = 14


def shifts_futile(negative_pivots, failed_at):
    """Whether the inertia shifts cannot help a step matrix with ``negative_pivots``: more than
    :data:`MAX_SHIFT_PIVOTS`, or no fewer than at the last iteration whose shifts all failed
    (``failed_at``; None if none has)."""
    return negative_pivots > MAX_SHIFT_PIVOTS or (failed_at is not None and negative_pivots >= failed_at)


class Shifts:
    """Whether an indefinite step tries the inertia shifts, and the memory ``skip_futile_shifts`` needs."""

    def __init__(self, enabled, skip_futile):
        self.enabled, self.skip_futile, self.failed_at = bool(enabled), bool(skip_futile), None

    def wanted(self, negative_pivots):
        return self.enabled and not (self.skip_futile and shifts_futile(negative_pivots, self.failed_at))

    def failed(self, negative_pivots):
        self.failed_at = negative_pivots


def projected_step(problem, z, energy, g, g_norm, rhs, pattern, step_rtol):
    """A line-search step along ``−K⁻¹ rhs`` with ``K`` the step matrix's PSD projection, else that
    shifted by 1e-6 max|diag K|: ``(accepted, mode, factorisations)`` (``accepted`` None if neither
    gave a descent step)."""
    hessian = getattr(problem, "step_hessian", problem.hessian)
    tried = 0
    for mode in ("project", "shift"):
        tried += 1
        K = hessian(z, project=True)
        if mode == "shift":
            K = shift_diagonal(K, 1e-6 * abs(K.diagonal()).max())
        _, d = factor_solve(K, rhs, pattern, step_rtol)
        if d is None or not descends(g, g_norm, d):
            continue
        accepted = _line_search(problem, z, d, energy, g, g_norm, expand=True)
        if accepted is not None:
            return accepted, mode, tried
    return None, mode, tried
