"""Newton's method for the discrete energy, with the exact sparse Hessian.

Robustness measures (issue #2, section 4):

- a descent check on the Newton direction; when it fails, or the line search does,
  the step is recomputed with a positive semi-definite Hessian (only when needed:
  the bulk's tangent modulus ∂²W/∂F² and each skin block with their negative
  eigenvalues set to zero), then with a diagonal shift;
- a backtracking line search in which an inverted tet or a degenerate skin triangle
  counts as infinite energy;
- an Armijo test on the energy that falls back to a decrease of the gradient norm
  once energy differences are below round-off (the last digits of a converged solve).

Cost (issue #21): with ``reuse > 0`` an iteration may step with the factor of an earlier
Hessian (a chord step) while the gradient norm keeps falling fast enough. On ultra-thin
such an iteration costs a gradient and a triangular solve, ~10 ms, against ~60 ms for an
assembly and a factorisation; but chord steps contract less, and on ultra-thin cold solves
took 0.69-1.10× the time, standing the slowest, and ended at another of the standing
posture's minima at one of five points (docs/benchmarks.md, "Speed"). So ``reuse`` defaults to 0
here; the forward solves use ``SolverOptions.reuse_factor`` (0.5), measured on the path without a
δ phase.

The step matrix is ``problem.step_hessian(z, project)`` where the problem has one (e.g. with
the primal-dual sliding blocks of :class:`~breastcore.fem.sliding_dual.SlidingDual`), else
``problem.hessian``. With ``inertia_shift``, an indefinite step matrix ``K`` is first replaced
by ``K + σ |diag K|`` for σ in :data:`~breastcore.nonlinear.indefinite.INERTIA_SHIFTS`, the first
whose factor has no negative pivot: the PSD projection stiffens every skin and bulk block, so its
steps along a soft mode are far too short (the line search then doubles them up to 2¹⁰), while a
shift just large enough for positive definiteness keeps the rest of the curvature.

With ``deep_skips``, the fresh steps after an exact factorisation with more than
:data:`~breastcore.nonlinear.indefinite.DEEP_INDEFINITE_PIVOTS` negative pivots take the PSD
projection directly: there the exact factorisation would only report the inertia (with
``skip_futile_shifts`` the shifts are not tried at that depth either).

The directions solve for ``problem.step_gradient(z, g)`` where the problem has one (sliding nodes
released by :meth:`~breastcore.fem.sliding_dual.SlidingDual.release`), else for the gradient ``g``;
the descent test and the line search always use ``g``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from breastcore.linalg.factorization import REFINEMENT_RTOL, factor_solve, shift_diagonal
from breastcore.nonlinear.indefinite import DEEP_INDEFINITE_PIVOTS, INERTIA_SHIFTS, Shifts, projected_step
from breastcore.nonlinear.line_search import _line_search, _norm, descends

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class NewtonResult:
    """Outcome of one Newton solve (frozen: it is a record, not a state).

    Attributes
    ----------
    x : (n,) array
        Free dofs at the last iterate, m.
    success : bool
        Whether ``gradient_norm <= tolerance``.
    iterations : int
        Newton iterations taken.
    gradient_norm : float
        Euclidean norm of the free-dof gradient at ``x``, N.
    tolerance : float
        The stopping tolerance on ``gradient_norm``, N.
    energy : float
        Energy at ``x``, J.
    projected_steps : int
        Iterations that needed the PSD projection or a shift.
    factorizations : int
        Matrices factorised: one per iteration, plus one per inertia shift tried
        (≤ :data:`~breastcore.nonlinear.indefinite.INERTIA_SHIFTS`) and one each for the projection
        and its shift where the exact step is refused; fewer than ``iterations`` with chord steps.
    history : tuple of float
        Gradient norm before each iteration, N.
    message : str
        Why it stopped.
    negative_pivots : int or None
        Negative eigenvalues of the exact Hessian (PARDISO's inertia; ``None`` if
        unknown) where it was last factorised: at ``x`` if ``inertia_at_x``, else at
        the iterate before the last step (a Newton solve factorises before it steps),
        or, after chord steps (``reuse > 0``) or steps that skipped the exact factorisation
        (``deep_skips``), at the iterate of the last exact factor.
    inertia_at_x : bool
        Whether ``negative_pivots`` is the inertia at ``x`` itself. Non-zero
        inertia at ``x`` means the equilibrium is a saddle, not a minimum.
    """

    x: np.ndarray
    success: bool
    iterations: int
    gradient_norm: float
    tolerance: float
    energy: float
    projected_steps: int
    history: tuple
    message: str
    negative_pivots: int | None = None
    inertia_at_x: bool = False
    factorizations: int = 0


#: Iterations without progress after which :func:`newton` stops (see :func:`_stagnated`).
STAGNATION_WINDOW = 10


def _stagnated(history, energies, scale):
    """Whether the last :data:`STAGNATION_WINDOW` iterations made no progress at all.

    No progress: the gradient norm never fell below 0.9 × its best before the
    window, and the energy changed by at most 1e-12 × ``scale`` (round-off).
    This happens when the tolerance lies below the gradient's round-off floor
    (e.g. λ/μ = 1e4 with a large load, where the forces cancel to ~1e-9 N):
    without the test such a solve spends every iteration of every continuation
    halving there (1,600 iterations in one no-inverse-crime identification step).
    """
    w = STAGNATION_WINDOW
    if len(history) <= 2 * w:
        return False
    best_before = min(history[:-w])
    flat = max(energies[-w - 1:]) - min(energies[-w - 1:]) <= 1e-12 * scale
    return flat and min(history[-w:]) > 0.9 * best_before


def _stop(history, energies, scale, at_limit):
    """Why Newton stops before a step at this iterate (None: it goes on); ``history[-1]`` is |g| here."""
    if not np.isfinite(history[-1]):
        return "non-finite gradient"
    if at_limit:
        return "iteration limit"
    if _stagnated(history, energies, scale):
        return f"stagnated: |g| at its round-off floor for {STAGNATION_WINDOW} iterations"
    return None


def newton(problem, z0, tolerance, max_iterations=50, avoid_saddles=False, reuse=0.0, inertia_shift=False,
           step_rtol=REFINEMENT_RTOL, skip_futile_shifts=False, deep_skips=0):
    """Minimise ``problem`` from ``z0`` until the gradient norm is at most ``tolerance``.

    Parameters
    ----------
    problem : object
        Provides ``value(z)`` (``inf`` where inadmissible), ``gradient(z)``,
        ``hessian(z, project)`` (CSR, free dofs) and ``energy_scale`` (J, a
        typical energy magnitude used for round-off tests); optionally
        ``pattern``, the :class:`SymmetricPattern` of its Hessians.
    z0 : (n,) array
        Admissible starting free dofs.
    tolerance : float
        Stopping tolerance on the Euclidean norm of the gradient, N.
    max_iterations : int
    avoid_saddles : bool
        If True, an exact Hessian with negative pivots (indefinite, by PARDISO's
        inertia) is not used: the step comes from the projected Hessian instead,
        whose directions lead downhill to a minimum rather than to the nearest
        stationary point. Used after a saddle was detected (see
        :func:`breastcore.nonlinear.saddle.escape_saddle`); without inertia (SuperLU) it
        has no effect.
    reuse : float
        Chord steps: while the last step cut the gradient norm to at most ``reuse`` times
        its previous value, the next direction is solved with the last exact factor
        (no new Hessian) and the line search is tried on it; a failed chord step falls
        back to a fresh factorisation in the same iteration. 0 (default): a fresh
        factorisation every iteration (the method before issue #21).
    inertia_shift : bool
        Where the step matrix has negative pivots (or gives no descent), first try the
        shifts of :data:`~breastcore.nonlinear.indefinite.INERTIA_SHIFTS` (module notes), then the PSD
        projection. False (default): the projection directly (the method before). Needs PARDISO's inertia.
    step_rtol : float
        Directions are solved to ``‖K d + b‖ ≤ step_rtol ‖b‖`` (inexact Newton; ``b`` the right-hand
        side, ``g`` but for released sliding nodes, module notes); an exact or chord
        step that ends the solve is retaken refined (:func:`_refined_if_last`). Default: refined.
    skip_futile_shifts : bool
        With ``inertia_shift``: go to the projection directly where the shifts cannot help
        (:func:`~breastcore.nonlinear.indefinite.shifts_futile`). False (default): try them at every
        indefinite step.
    deep_skips : int
        After an exact factorisation with more than
        :data:`~breastcore.nonlinear.indefinite.DEEP_INDEFINITE_PIVOTS` negative pivots, this many
        fresh steps take the PSD projection directly (a failed one falls back to the full step); only
        where that is the step taken anyway (``_Steps``). 0 (default): none skipped.

    Returns
    -------
    NewtonResult
        ``success`` is False if the iteration limit was hit or no step decreased
        the energy; callers decide whether to retry (continuation) or raise.
    """
    z = np.array(z0, dtype=float)
    energy = problem.value(z)
    if not np.isfinite(energy):
        raise ValueError("Newton start is inadmissible (inverted tet or degenerate skin triangle)")
    history, energies = [], [energy]
    steps = _Steps(problem, reuse, avoid_saddles, Shifts(inertia_shift, skip_futile_shifts), step_rtol, deep_skips)
    g_next = None                                                    # the gradient at z, if known
    for it in range(max_iterations + 1):
        g = problem.gradient(z) if g_next is None else g_next
        g_norm = _norm(g)
        history.append(g_norm)
        if g_norm <= tolerance:
            return NewtonResult(z, True, it, g_norm, tolerance, energy, steps.projected, tuple(history), "converged",
                                steps.inertia, factorizations=steps.factorizations)
        message = _stop(history, energies, abs(energy) + problem.energy_scale, it == max_iterations)
        if message:
            break
        accepted, mode, used = steps.take(z, energy, g, g_norm, history)
        if accepted is None:
            message = "no descent step found (line search failed)"
            break
        step, z_new, energy_new = accepted
        g_next = None
        if step_rtol > REFINEMENT_RTOL and used is not None:
            z_new, energy_new, g_next = _refined_if_last(problem, used[0], z, used[1], step, z_new, energy_new,
                                                         tolerance)
        z, energy = z_new, energy_new
        energies.append(energy)
        log.debug("newton it=%d |g|=%.3e step=%.3g E=%.9e mode=%s neg=%s", it, g_norm, step, energy, mode,
                  steps.inertia)
    return NewtonResult(z, False, len(history) - 1, history[-1], tolerance, energy, steps.projected, tuple(history),
                        message, steps.inertia, factorizations=steps.factorizations)


class _Steps:
    """How :func:`newton` takes a step: a chord step with the kept factor where it may, else a fresh one.

    Counts the factorisations and the modified (projected or shifted) steps, and keeps the inertia of
    the last exact factor. ``deep_skips`` act only where a skipped step is the one taken anyway: an
    indefinite exact step refused (``inertia_shift`` or ``avoid_saddles``) and no shift tried above
    :data:`~breastcore.nonlinear.indefinite.MAX_SHIFT_PIVOTS` (no shifts, or ``skip_futile_shifts``).
    """

    def __init__(self, problem, reuse, avoid_saddles, shifts, step_rtol, deep_skips=0):
        self.problem, self.reuse, self.avoid_saddles, self.shifts = problem, reuse, avoid_saddles, shifts
        self.step_rtol, self.pattern = step_rtol, getattr(problem, "pattern", None)   # reuse the symbolic analysis
        self.kept = self.inertia = None                              # kept: the last exact factor (chord steps)
        self.factorizations = self.projected = 0
        same = (avoid_saddles or shifts.enabled) and (shifts.skip_futile or not shifts.enabled)
        self.deep_skips, self.skips_left = (deep_skips if same else 0), 0

    def take(self, z, energy, g, g_norm, history):
        """``(accepted, mode, used)``: the line search's outcome (None: no descent step), the step's
        mode, and ``(factor, right-hand side)`` of its unmodified direction (None for a modified one)."""
        if self.kept is not None and g_norm <= self.reuse * history[-2]:
            accepted = _chord_step(self.problem, self.kept, z, energy, g, g_norm, self.step_rtol)
            if accepted is not None:
                return accepted, "chord", (self.kept, g)
        if self.skips_left > 0:                  # deep in an indefinite phase: no exact factorisation
            self.skips_left -= 1          # (an earlier release is keyed to its own positions: not applied here)
            accepted, mode, tried = projected_step(self.problem, z, energy, g, g_norm, g, self.pattern,
                                                    self.step_rtol)
            self.factorizations += tried
            if accepted is not None:               # self.inertia stays the last exact factor's
                self.projected, self.kept = self.projected + 1, None
                return accepted, f"{mode} (inertia skipped)", None
        accepted, mode, factor, tried, rhs = _fresh_step(self.problem, z, energy, g, g_norm, self.pattern,
                                                         self.avoid_saddles, self.shifts, self.step_rtol)
        self.factorizations += tried
        self.inertia = None if factor is None else factor.negative_pivots
        self.projected += accepted is not None and mode != "exact"
        exact = accepted is not None and mode == "exact"
        # a released step's factor is kept only without released nodes: chord steps solve for g
        self.kept = factor if exact and self.reuse > 0 and rhs is g else None
        deep = self.inertia is not None and self.inertia > DEEP_INDEFINITE_PIVOTS
        self.skips_left = self.deep_skips if deep else 0
        return accepted, mode, (factor, rhs) if exact else None


def _refined_if_last(problem, factor, z0, rhs, step, z, energy, tolerance):
    """``(z, energy, gradient at z)`` after an inexact step from ``z0`` along ``−factor⁻¹ rhs``;
    where that step ends the solve (``|g(z)| ≤ tolerance``), the same step along the direction
    refined to ``REFINEMENT_RTOL``, if that point is an equilibrium to the tolerance too.

    The inexact direction's error is ``step_rtol``-small but not smooth in the data (single-precision
    round-off): an equilibrium that ends on it differs from one solve to the next by up to the
    tolerance, enough to spoil central differences of M(Λ) at steps of 1e-5 (1e-6 of the
    Jacobian, against 6e-9 with the last direction refined) and to make LM's end game take more
    evaluations (``docs/benchmarks.md``, "Inexact Newton steps"). A double-precision factor's
    direction is refined already.
    """
    g_new = problem.gradient(z)
    if not _norm(g_new) <= tolerance or not factor.mixed:
        return z, energy, g_new
    try:
        d = -factor.solve(rhs)
    except (RuntimeError, ValueError):
        return z, energy, g_new
    refined = z0 + step * d
    value = problem.value(refined) if np.all(np.isfinite(refined)) else np.inf
    if not np.isfinite(value):
        return z, energy, g_new
    g_refined = problem.gradient(refined)
    return (refined, value, g_refined) if _norm(g_refined) <= tolerance else (z, energy, g_new)


def _fresh_step(problem, z, energy, g, g_norm, pattern, avoid_saddles, shifts=None, step_rtol=REFINEMENT_RTOL):
    """A line-search step along ``−K⁻¹ g`` with ``K`` the exact Hessian (the step matrix and right-hand
    side of released sliding nodes where there are any), else (``inertia_shift``) the smallest of
    :data:`~breastcore.nonlinear.indefinite.INERTIA_SHIFTS` that makes the plain step matrix positive
    definite, else its PSD projection, else that shifted (:func:`~breastcore.nonlinear.indefinite.projected_step`):
    the modified steps solve for ``g`` itself, so that they descend.

    ``shifts``: a :class:`~breastcore.nonlinear.indefinite.Shifts` (None: no shifts). Returns
    ``(accepted, mode, exact_factor, factorisations, rhs)``: ``accepted`` as
    :func:`~breastcore.nonlinear.line_search._line_search` (None if no mode gave a descent
    step), the mode that gave it, the exact Hessian's factor (its inertia; None if it
    failed), and the right-hand side the exact direction solved for: ``problem.step_gradient(z, g)``
    where the problem has one (released sliding nodes; ``g`` itself where none is), else ``g``. The
    descent test and the line search use ``g``.
    """
    hessian = getattr(problem, "step_hessian", problem.hessian)
    rhs = problem.step_gradient(z, g) if hasattr(problem, "step_gradient") else g
    inertia_shift = shifts is not None and shifts.enabled
    exact, tried = None, 0
    K = hessian(z, project=False)
    tried += 1
    factor, d = factor_solve(K, rhs, pattern, step_rtol)
    exact = factor
    indefinite = factor is not None and bool(factor.negative_pivots)
    if d is not None and descends(g, g_norm, d) and not (indefinite and (avoid_saddles or inertia_shift)):
        accepted = _line_search(problem, z, d, energy, g, g_norm)
        if accepted is not None:
            return accepted, "exact", exact, tried, rhs
    if rhs is not g:            # the released step failed: the modified steps are the plain ones, for g
        rhs, K = problem.step_gradient(z, g, release=False), None    # K: assembled again only for the shifts
    if inertia_shift and factor is not None and factor.negative_pivots is not None and \
            shifts.wanted(factor.negative_pivots):
        K = hessian(z, project=False) if K is None else K
        scale = np.abs(K.diagonal())
        for sigma in INERTIA_SHIFTS:
            tried += 1
            shifted, d = factor_solve(shift_diagonal(K, sigma * scale), rhs, pattern, step_rtol)
            if shifted is None or shifted.negative_pivots or not descends(g, g_norm, d):
                continue
            accepted = _line_search(problem, z, d, energy, g, g_norm, expand=True)
            if accepted is not None:
                return accepted, f"shift{sigma:g}", exact, tried, rhs
        if factor.negative_pivots:                                   # (a definite K whose step failed: not a verdict)
            shifts.failed(factor.negative_pivots)
    accepted, mode, more = projected_step(problem, z, energy, g, g_norm, rhs, pattern, step_rtol)
    return accepted, mode, exact, tried + more, rhs


def _chord_step(problem, factor, z, energy, g, g_norm, step_rtol=REFINEMENT_RTOL):
    """A line-search step along ``−K₀⁻¹ g`` with an earlier exact factor ``K₀``; None if it is no descent.

    Only a full step is taken: a chord direction that needs backtracking says that ``K₀``
    no longer models the energy here, and a fresh factorisation is cheaper than a search.
    """
    try:
        d = -factor.solve(g, step_rtol)
    except (RuntimeError, ValueError):
        return None
    if not np.all(np.isfinite(d)) or not descends(g, g_norm, d):
        return None
    return _line_search(problem, z, d, energy, g, g_norm, min_step=1.0)
