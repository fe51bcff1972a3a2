"""Reaching one posture's equilibrium: continuation in gravity, then in the smoothing δ.

A :class:`ForwardModel` holds one fixed-topology mesh; ``(R, H)`` move its nodes
through the smooth :class:`~breastcore.model.geometry.CapMap`. :func:`solve_posture`
reaches equilibrium by adaptive continuation, first in the gravity load factor
and then in the Chassaignac smoothing δ down to its target, with a Newton solve
(or the paper's conjugate-gradient baseline) at each step.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np

from breastcore.forward.records import PostureSolution, SolveError
from breastcore.linalg.factorization import hessian_factor, hessian_inertia
from breastcore.model.parameters import Parameters
from breastcore.model.postures import Posture
from breastcore.nonlinear.newton import NewtonResult, newton
from breastcore.nonlinear.saddle import escape_saddle


log = logging.getLogger(__name__)


def _cg_minimiser(model):
    """The CG baseline with :func:`~breastcore.nonlinear.newton.newton`'s call signature (``avoid_saddles`` has no
    effect: CG follows the gradient and is not drawn to saddles as Newton's step is)."""
    from breastcore.nonlinear.cg import conjugate_gradient

    def minimise(problem, z, tolerance, max_iterations=None, avoid_saddles=False):
        return conjugate_gradient(problem, z, tolerance, model.options.cg_max_iterations)
    return minimise


def _newton(model, problem, z, tolerance):
    opts = model.options
    return newton(problem, z, tolerance, opts.max_iterations, reuse=opts.reuse_factor, inertia_shift=opts.inertia_shift,
                  step_rtol=opts.step_rtol, skip_futile_shifts=opts.skip_futile_shifts,
                  deep_skips=opts.deep_indefinite_skips)


def _minimise(model, problem, z, tolerance):
    """One minimisation; a numerical breakdown on the way (an element so degenerate that its eigen-solve
    fails, a non-finite Hessian) is a failed step, which continuation halves and, if it persists,
    reports as a :class:`SolveError` with its diagnostics, never a bare ``LinAlgError``."""
    try:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):    # non-finite values are tested
            return _minimise_unguarded(model, problem, z, tolerance)
    except np.linalg.LinAlgError as err:
        with np.errstate(all="ignore"):
            g_norm, energy = float(np.linalg.norm(problem.gradient(z))), float(problem.value(z))
        log.info("numerical breakdown in a minimisation (%s)", err)
        return NewtonResult(z, False, 0, g_norm, tolerance, energy, 0, (g_norm,), f"numerical breakdown: {err}")


def _minimise_unguarded(model, problem, z, tolerance):
    if model.options.method == "cg":
        return _cg_minimiser(model)(problem, z, tolerance)
    result = _newton(model, problem, z, tolerance)
    if result.success and result.negative_pivots:                  # an unstable equilibrium: leave it
        return escape_saddle(problem, result, model.options.max_iterations)
    iterations, factorizations = result.iterations, result.factorizations
    for _ in range(model.options.max_extensions):                  # still going downhill: keep going
        if result.success or result.message != "iteration limit":
            break
        start_energy = problem.value(z)
        if not start_energy - result.energy > 1e-3 * abs(result.energy):
            break
        z = result.x
        log.debug("iteration limit with the energy still falling (%.6e → %.6e): continuing", start_energy,
                  result.energy)
        result = _newton(model, problem, z, tolerance)
        iterations += result.iterations
        factorizations += result.factorizations
    if iterations == result.iterations:
        return result
    return dataclasses.replace(result, iterations=iterations, factorizations=factorizations)


def _diagnostics(problem, x):
    """``(min det F, max principal stretch)`` at ``x``."""
    return problem.bulk.deformation_extremes(x)


def solve_posture(model, params: Parameters, posture: Posture, start=None) -> PostureSolution:
    r"""Minimise ``J_h`` for one posture of ``model`` (a :class:`~breastcore.forward.model.ForwardModel`)
    by adaptive continuation.

    The path parameter ``t`` runs over ``[0, 1]`` for the gravity load factor
    (at δ = max(δ, ``smoothing_start``)) and then over ``[1, 2]`` for δ, lowered
    log-linearly to its target, at most one decade per step. Each step is a Newton
    solve warm-started from the last converged state; a failed step is halved, a
    good one lengthened ×2.
    With ``start`` (a previous solution, ``(N, 3)``), the target problem is tried
    directly first, and continuation in δ from ``start`` is the fallback; without a δ
    phase (target δ ≥ ``smoothing_start``) the fallback is the cold continuation.

    Raises
    ------
    SolveError
        When a continuation step falls below ``options.min_step``, or the final
        δ step has failed ``options.max_final_attempts`` times.
    """
    opts = model.options
    tic = time.perf_counter()
    tolerance = model.tolerance(params, posture)
    loose = tolerance * opts.stage_rtol / opts.rtol
    delta_target = params.smoothing
    delta_start = max(delta_target, opts.smoothing_start)
    decades = np.log10(delta_start / delta_target)

    def level(t):
        if t <= 1.0:
            return t, delta_start
        return 1.0, delta_start * 10.0 ** (-decades * (t - 1.0))

    iterations = 0
    steps = 0
    reference = model.reference(params.R, params.H)
    t, x = 0.0, reference
    kind = "cold"
    if start is not None:
        problem, result, t, x = _direct_attempt(model, params, posture, start, reference, tolerance, delta_start)
        if result is not None:
            iterations, steps = result.iterations, 1
            if result.success:
                return _finish(model, problem, result, posture, iterations, steps, tic, "warm")
        kind = "warm fallback"
        if decades == 0:
            # No δ phase to continue in from the start: re-solving the same target problem from
            # the same start would fail the same way, so continue cold from the reference.
            t, x = 0.0, reference
            log.info("%s: the warm start failed; cold continuation", posture.name)
    t_end = 2.0 if decades > 0 else 1.0
    max_delta_step = 1.0 / max(decades, 1.0)          # δ falls at most one decade per step
    dt = 1.0 if t < 1.0 else max_delta_step
    final_failures = 0
    x_delta = None                                    # δ at which x is an equilibrium (None: unknown)
    while True:
        t_next = min(t + dt, 1.0 if t < 1.0 else t_end)
        load, delta = level(t_next)
        problem = model.problem(params, posture, load, delta)
        final = t_next >= t_end
        z = problem.free(x)
        if t >= 1.0 and x_delta is not None and delta < x_delta:
            z = _smoothing_predictor(model, problem, x, reference, x_delta, delta, z)
        result = _minimise(model, problem, z, tolerance if final else loose)
        iterations += result.iterations
        steps += 1
        log.debug("%s: step t=%.4f load=%.4g δ=%.3e: %s in %d iterations", posture.name, t_next, load, delta,
                  result.message, result.iterations)
        if result.success:
            if final:
                return _finish(model, problem, result, posture, iterations, steps, tic, kind)
            t, x, x_delta = t_next, problem.full(result.x), delta
            dt = min(2.0 * dt, 1.0 if t < 1.0 else max_delta_step)
            continue
        final_failures += final and t >= 1.0           # a failed last δ step; a load step is halved on
        log.info("%s: continuation step t=%.4f→%.4f failed (%s); halving", posture.name, t, t_next, result.message)
        dt *= 0.5
        if dt < opts.min_step or final_failures >= opts.max_final_attempts:
            min_det = _diagnostics(problem, problem.full(result.x))[0]
            load, delta = level(t)
            why = "continuation stalled" if dt < opts.min_step else \
                f"final step failed {final_failures} times"
            raise SolveError(f"{why}: {result.message}", iterations=iterations,
                             gradient_norm=result.gradient_norm, tolerance=tolerance, min_det_F=min_det,
                             load_factor=load, smoothing=delta, posture=posture.name)


def _direct_attempt(model, params, posture, start, reference, tolerance, delta_start):
    """Solve the target problem directly from a warm ``start``.

    Returns ``(problem, result, t, x)``: the Newton result (None when ``start`` is not
    admissible), and where continuation resumes if it failed: from ``start`` in δ
    (``t = 1``), or from the reference state when ``start`` is inadmissible at δ_start.
    """
    problem = model.problem(params, posture)
    start = np.asarray(start, dtype=float)
    scaled = _rescale_start(problem, start, reference)
    if np.isfinite(problem.value(problem.free(scaled))) or not np.isfinite(problem.value(problem.free(start))):
        start = scaled
    z = problem.free(start)
    result = _minimise(model, problem, z, tolerance) if np.isfinite(problem.value(z)) else None
    if result is not None and result.success:
        return problem, result, 1.0, start
    t, x = 1.0, start
    if not np.isfinite(model.problem(params, posture, 1.0, delta_start).value(z)):
        t, x = 0.0, reference
    return problem, result, t, x


def _rescale_start(problem, start, reference):
    """A warm start whose fixed fold nodes are moved onto their new positions.

    A start computed for other ``(R, H)`` has its fold nodes on the old base rim;
    the problem fixes them on the new one, and the tets at the fold, which the
    standing posture compresses to ``det F`` ~ 1e-5, invert under that jump. The
    start is scaled in ``x`` and ``z`` (the torso plane) by the least-squares
    factor that carries its fold nodes to their new positions: a linear map with
    positive determinant, so every tet keeps its orientation. The smooth cap map
    scales the reference in ``x`` and ``z`` by the same factor (the base radius
    ratio), so this also transfers most of the change of reference; on
    ultra-thin, after a 1 % change of all six parameters, it cuts the warm
    Newton iterations from 11-44 to 3-5. A start for the same ``(R, H)`` is
    returned unchanged (factor 1).
    """
    fixed = ~problem.assembler.free.reshape(-1, 3)[:, 0]            # fold nodes (fixed in x)
    old, new = start[fixed][:, [0, 2]], reference[fixed][:, [0, 2]]
    norm = float(np.sum(old * old))
    if not fixed.any() or norm == 0.0:
        return start
    scaled = start.copy()
    scaled[:, [0, 2]] *= float(np.sum(old * new)) / norm
    return scaled


#: Back nodes that slip less than this many δ count as sticking in :func:`_smoothing_predictor`.
STICK_SLIPS = 3.0


def _smoothing_predictor(model, problem, x, reference, delta_old, delta_new, z):
    """Starting free dofs for a δ step: the slip of sticking back nodes scaled by ``δ_new/δ_old``.

    With the tangential force on a back node held fixed, the equilibrium slip of
    ``w u / sqrt(|u|² + δ²) = f`` is proportional to δ, so a node in the stick zone
    (``|u| <`` :data:`STICK_SLIPS` δ_old) is moved to ``u δ_new/δ_old``; slipping
    nodes keep their slip. Newton from the unscaled slip overshoots (the smoothed
    norm is nearly flat radially for ``|u| ≫ δ``) and needs many damped steps.
    Returns ``z`` unchanged if the predicted state is inadmissible.
    """
    back = np.flatnonzero(model.mesh.back)
    u = x[back] - reference[back]
    stick = back[np.linalg.norm(u, axis=1) < STICK_SLIPS * delta_old]
    if stick.size == 0:
        return z
    predicted = np.array(x, dtype=float, copy=True)
    predicted[stick] = reference[stick] + (x[stick] - reference[stick]) * (delta_new / delta_old)
    z_pred = problem.free(predicted)
    return z_pred if np.isfinite(problem.value(z_pred)) else z


def _settle(model, problem, result):
    """``result`` with the inertia of the exact Hessian at its own point, a saddle left first.

    Newton's inertia comes from the Hessian it factorised before its last step, and a
    CG solve or a warm solve that needs no iteration factorises none: the inertia of
    the returned equilibrium is computed here (one factorisation, unless the saddle
    escape already did it). A saddle found so is left by the solve's own method
    (:func:`~breastcore.nonlinear.saddle.escape_saddle`), for Newton and CG alike.
    """
    if not result.inertia_at_x:
        factor = hessian_factor(problem, result.x)
        result = dataclasses.replace(result, negative_pivots=None if factor is None else factor.negative_pivots,
                                     inertia_at_x=True)
        if factor is not None and factor.negative_pivots == 0:     # a stable equilibrium: its Jacobian's factor
            model.remember_tangent(problem, problem.full(result.x), factor)
    if not result.negative_pivots:
        return result
    minimise = _cg_minimiser(model) if model.options.method == "cg" else newton
    escaped = escape_saddle(problem, result, model.options.max_iterations, minimise=minimise)
    if not escaped.inertia_at_x:
        escaped = dataclasses.replace(escaped, negative_pivots=hessian_inertia(problem, escaped.x), inertia_at_x=True)
    return escaped


def _finish(model, problem, result, posture, iterations, steps, tic, kind):
    extra_iterations = result.iterations
    result = _settle(model, problem, result)
    iterations += result.iterations - extra_iterations
    x = problem.full(result.x)
    min_det, stretch = _diagnostics(problem, x)
    # ``kind`` (cold, warm or warm fallback) is read back by breastcore.studies.paper_scene_logs
    log.info("%s: converged in %d iterations (%d continuation steps, %s start), |g|=%.3e N", posture.name,
             iterations, steps, kind, result.gradient_norm)
    pivots = None if result.negative_pivots is None else int(result.negative_pivots)   # at x; > 0: a saddle kept
    return PostureSolution(posture, x, True, iterations, steps, result.gradient_norm, result.tolerance,
                           result.energy, min_det, stretch, time.perf_counter() - tic, negative_pivots=pivots)
