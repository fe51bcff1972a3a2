"""Identification of ``Λ = (R, H, λ, μ, λ_s, μ_s)`` from measurements (issue #3, spec §5).

Cost: ``E(Λ) = Σ_i w_i (M_i(Λ)/M̄_i − 1)²``.

Methods
-------
``lm`` (default)
    Levenberg–Marquardt in trust-region form (``scipy.optimize.least_squares``,
    ``method="trf"``, exact subproblem) in the unconstrained variables
    ``z = (ln R, logit(H/R), ln λ, ln μ, ln λ_s, ln μ_s)``: the bounds
    ``R > 0``, ``0 < H < R`` and positive moduli hold by construction, and
    the log scaling makes the six columns comparable. A step whose forward solve
    fails returns a large residual, so it is rejected and the trust region shrinks
    (the damping grows): a failed solve never ends the run.
``gauss-newton``
    The paper's method: forward-difference Jacobian with relative step ``ε``,
    the step ``ΔΛ/Λ = (JᵀJ)⁻¹ Jᵀ (1 − m)`` (the paper's equation carries a stray
    factor 2, which would double the Gauss–Newton step), stopped when
    ``E(Λⁿ) − E(Λⁿ⁺¹) < ε_m``.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from breastcore.forward.records import SolveError
from breastcore.inverse.options import IdentificationOptions
from breastcore.model.parameters import ParameterError

log = logging.getLogger(__name__)

#: Residual returned for a Λ whose forward solve fails: cost ≫ any real one.
FAILED_RESIDUAL = 1e3
#: LM's cap on residual evaluations (trial points, accepted or not) per allowed iteration.
MAX_EVALUATIONS_PER_ITERATION = 3


@dataclass
class IdentificationResult:
    """History and outcome of one identification. Parameters in SI units."""

    success: bool
    message: str
    estimate: np.ndarray
    parameters: list = field(default_factory=list)        # per iteration, (6,)
    cost: list = field(default_factory=list)              # per iteration, E
    measurement_error: list = field(default_factory=list) # per iteration, (posture, quantity) M/M̄ − 1
    wall_time: list = field(default_factory=list)         # per iteration, s since start
    jacobian: np.ndarray | None = None                    # (posture, quantity, 6) ∂(M/M̄)/∂ln Λ
    solutions: dict | None = None
    forward_solves: int = 0
    failed_solves: int = 0
    branch_restarts: int = 0                              # runs continued with cold solves (see identify)
    branch_drift: float = 0.0                             # max |M_warm/M_cold − 1| at the last check
    iterations: int = 0                                   # accepted steps, over all runs (≤ max_iterations)


def to_unconstrained(values):
    R, H, *moduli = np.asarray(values, float)
    s = H / R
    return np.array([np.log(R), np.log(s / (1 - s)), *np.log(moduli)])


def from_unconstrained(z):
    z = np.asarray(z, float)
    R = np.exp(z[0])
    return np.array([R, R / (1 + np.exp(-z[1])), *np.exp(z[2:])])


def unconstrained_chain(values):
    """``dΛ/dz`` (6×6) of :func:`from_unconstrained` at ``Λ = values``."""
    R, H = values[0], values[1]
    s = H / R
    T = np.diag(np.asarray(values, float))
    T[1, 1] = R * s * (1 - s)
    T[1, 0] = H
    return T


def relative_jacobian(mm, values, solutions, options, warm):
    """``∂M/∂Λ · Λ / M̄``-ready Jacobian ``∂M/∂Λ`` (posture, quantity, 6), SI.

    The forward differences' solves start from ``solutions``, which ``warm`` then
    remembers (they are where the next step starts from).
    """
    if options.jacobian == "implicit":
        return mm.implicit_jacobian(values, solutions)
    dM = mm.fd_jacobian(values, solutions, options.fd_step)
    warm.remember(solutions, values)
    return dM


def too_few_weighted(weights, parameters) -> str | None:
    """Why the measurements of ``weights`` (posture, quantity) cannot determine ``parameters``
    parameters, with what to do; None when at least ``parameters`` of them have weight > 0."""
    weights = np.asarray(weights, float)
    weighted = int(np.count_nonzero(weights > 0))
    if weighted >= parameters:
        return None
    why = "every weight is 0" if weighted == 0 else f"only {weighted} of {weights.size} measurements have weight > 0"
    advice = ("measure at least two postures (5 measurements each)" if weights.shape[0] < 2 else
              "give weight > 0 to at least as many measurements as there are parameters")
    return f"{why}: {weighted} measurements cannot determine {parameters} parameters; {advice}"


def identify(mm, target, initial, options=IdentificationOptions(), weights=None, warm=None) -> IdentificationResult:
    """Find Λ minimising ``E`` for the measurements ``target`` (posture, quantity), SI units.

    ``warm``: the :class:`~breastcore.inverse.warm_start.WarmStarts` the first solve starts
    from (default: none, a cold solve at ``initial``); the run keeps its own afterwards.

    Raises
    ------
    SolveError
        Only if the forward solve fails at the initial guess.
    ValueError
        If fewer measurements carry weight than there are parameters (e.g. one posture's
        five for six): Λ would not be determined and its intervals would be meaningless.
    """
    if getattr(mm, "warm_radius", options.warm_radius) != options.warm_radius:
        raise ValueError(f"the measurement model's warm_radius ({mm.warm_radius}) is not the options' "
                         f"({options.warm_radius}): build it with MeasurementModel.from_problem")
    target = np.asarray(target, float)
    w = np.ones_like(target) if weights is None else np.asarray(weights, float)
    refusal = too_few_weighted(w, len(initial))
    if refusal:
        raise ValueError(refusal)
    sqrt_w = np.sqrt(w)
    result = IdentificationResult(False, "", np.asarray(initial, float))
    tic = time.perf_counter()
    implicit = options.jacobian == "implicit"
    warm = mm.warm_starts() if warm is None else warm
    solutions = mm.solve(initial, warm, jacobian=implicit)  # a failure here is the caller's to report
    warm.remember(solutions, initial)

    def record(values, sols):
        error = mm.measure(sols) / target - 1.0
        result.parameters.append(np.array(values, float))
        result.measurement_error.append(error)
        result.cost.append(float(np.sum(w * error**2)))
        result.wall_time.append(time.perf_counter() - tic)
        log.info("identify it=%d E=%.6e Λ=%s", len(result.cost) - 1, result.cost[-1],
                 np.array2string(np.asarray(values), precision=6, max_line_width=1000))   # one line per iteration

    record(initial, solutions)
    run = _levenberg_marquardt if options.method == "lm" else _gauss_newton
    run(mm, target, sqrt_w, np.asarray(initial, float), solutions, options, result, record, warm)
    if mm.warm_radius > 0:
        _check_branch(mm, target, sqrt_w, options, result, record, run, warm)
    result.forward_solves = mm.solves
    final = result.parameters[-1]
    result.estimate = final
    if result.solutions is None:
        result.solutions = mm.solve(final, warm)
        warm.remember(result.solutions, final)
    dM = relative_jacobian(mm, final, result.solutions, options, warm)
    result.jacobian = dM * np.asarray(final)[None, None, :] / target[..., None]
    return result


#: A cost at which the data are fit to round-off (rms relative residual ~3e-9 over 15
#: measurements): LM stops there, and a branch drift found at such an estimate is not chased.
EXACT_FIT = 1e-16

#: Largest relative difference between warm- and cold-started measurements at the estimate.
BRANCH_TOL = 1e-6
#: Restarts after a branch drift (each re-anchored on the cold equilibria, then warm again).
BRANCH_RESTARTS = 2


def _check_branch(mm, target, sqrt_w, options, result, record, run, warm_starts):
    """Re-solve the estimate cold; if warm starts had drifted to another branch, go on from it.

    The standing posture can have more than one stable equilibrium. A chain of
    warm-started solves, each from the last accepted Λ, can follow another one than
    the cold solve (gravity continuation from the reference), and the
    identification can then stop at a Λ that fits that branch only: on the coarse
    mesh, from 30 % off, it stopped with λ_s 0.6 % wrong and E = 1.4e-7, while cold
    solves give E = 1.7e-6 at that Λ. When the cold measurements at the estimate
    differ from the warm ones by more than :data:`BRANCH_TOL`, the same method
    continues from the estimate, re-anchored on the cold equilibria, with warm
    starts again; at most :data:`BRANCH_RESTARTS` times, after which the drift
    that remains is recorded in ``result.branch_drift`` (and logged). The history
    records each cold re-evaluation as an iteration at the same Λ. When the
    estimate's equilibria were solved cold already (its step went beyond the
    warm-start radius), they are the cold ones: the check is skipped, with drift 0.

    Not continued: a run that did not converge (its iteration limit stands) or has
    no iterations left; a run whose weighted RMS drift
    ``sqrt(Σ w_i (M_warm/M_cold − 1)² / n)`` is at most the weighted RMS residual
    ``sqrt(E/n)`` of its fit (the
    branches differ by less than the model already misses the data by, so chasing
    the drift cannot improve the estimate beyond its own uncertainty: on the
    medium-thin mesh against reference-mesh data, drifts of 1-2e-3 against a
    residual of 4e-2 cost two restarts, 12 s of a 73 s run, and moved Λ by < 1 %);
    and a run whose warm equilibria fit the data exactly (cost ≤ :data:`EXACT_FIT`):
    they are equilibria of the model that reproduce every measurement. Runs on cold
    solves only are not tried: on the refined meshes the cold path itself jumps
    between neighbouring minima under relative changes of Λ as small as 1e-8
    (docs/identification.md), so an optimiser on cold solves meets a
    discontinuous M(Λ) and stalls; on ultra-thin such runs spent 8 s per
    evaluation without converging.
    """
    for attempt in range(BRANCH_RESTARTS + 1):
        values = np.array(result.parameters[-1], float)
        warm = result.solutions if result.solutions is not None else mm.solve(values, warm_starts)
        if mm.solved_cold(warm):                        # the last step was solved cold: nothing to check
            result.branch_drift = 0.0
            return
        try:
            cold = mm.solve(values)
        except (SolveError, ParameterError) as err:
            log.warning("identify: the cold re-solve at the estimate failed (%s); branch not checked", err)
            return
        result.branch_drift = float(np.max(np.abs(mm.measure(warm) / mm.measure(cold) - 1.0)))
        if result.branch_drift <= BRANCH_TOL or not result.success:    # a failed run is not extended
            return
        drift_rms = float(np.sqrt(np.mean((sqrt_w * (mm.measure(warm) / mm.measure(cold) - 1.0)) ** 2)))
        residual = float(np.sqrt(result.cost[-1] / target.size))
        if drift_rms <= residual:
            log.info("identify: warm and cold equilibria differ by %.2e (weighted RMS %.2e) at the estimate, "
                     "no more than the fit's weighted RMS residual %.2e; kept", result.branch_drift, drift_rms,
                     residual)
            return
        if result.iterations >= options.max_iterations:
            log.warning("identify: warm and cold equilibria differ by %.2e at the estimate; no iterations left "
                        "to continue from the cold ones", result.branch_drift)
            return
        if result.cost[-1] <= EXACT_FIT:                # the warm equilibria fit the data exactly
            log.info("identify: warm and cold equilibria differ by %.2e at the estimate; the warm ones "
                     "fit the data (E = %.2e), kept", result.branch_drift, result.cost[-1])
            return
        if attempt == BRANCH_RESTARTS:
            log.warning("identify: warm and cold equilibria still differ by %.2e at the estimate after %d "
                        "restarts; the estimate fits the warm ones", result.branch_drift, attempt)
            return
        log.warning("identify: warm starts drifted to another equilibrium branch (max |ΔM/M| = %.2e); "
                    "continuing from the cold equilibria", result.branch_drift)
        result.branch_restarts += 1
        warm_starts.remember(cold, values)
        result.solutions = cold
        record(values, cold)
        run(mm, target, sqrt_w, values, cold, options, result, record, warm_starts)


def _levenberg_marquardt(mm, target, sqrt_w, initial, solutions, options, result, record, warm):
    cache = {}

    def fun(z):
        values = from_unconstrained(z)
        try:
            sols = mm.solve(values, warm, jacobian=options.jacobian == "implicit")
        except (SolveError, ParameterError) as err:
            result.failed_solves += 1
            log.info("identify: step rejected, forward solve failed (%s)", err)
            return np.full(target.size, FAILED_RESIDUAL)
        cache[z.tobytes()] = (values, sols)
        return (sqrt_w * (mm.measure(sols) / target - 1.0)).ravel()

    def jac(z, *_):
        values, sols = cache[z.tobytes()]
        warm.remember(sols, values)                       # accepted point: warm start from here
        dM = relative_jacobian(mm, values, sols, options, warm)
        J = (sqrt_w[..., None] * dM / target[..., None]).reshape(target.size, -1)
        return J @ unconstrained_chain(values)

    def callback(intermediate_result):
        values, sols = cache[intermediate_result.x.tobytes()]
        result.solutions = sols
        record(values, sols)

    # trf's first trust radius is ‖x₀‖ (1 if x₀ = 0): solve in d = (z − z₀)/r so that it is r in z.
    z0 = to_unconstrained(initial)
    radius = options.initial_trust_radius

    def to_z(d):
        return z0 + radius * d

    cache[to_z(np.zeros_like(z0)).tobytes()] = (initial, solutions)

    # scipy also calls back after an iteration whose last trial step it rejected while
    # stopping (xtol): that one is neither counted nor recorded.
    last = {"x": np.zeros_like(z0), "cost": 0.5 * result.cost[-1], "converged": False, "plateau": False}

    def on_step(intermediate_result):
        x, cost = intermediate_result.x, float(intermediate_result["cost"])
        if np.array_equal(x, last["x"]):
            return
        step, x_norm, old_cost = np.linalg.norm(x - last["x"]), np.linalg.norm(last["x"]), last["cost"]
        last.update(x=x.copy(), cost=cost)
        callback(_Point(to_z(x)))
        result.iterations += 1
        if old_cost - cost < options.cost_rtol * old_cost:
            last["plateau"] = True
            raise StopIteration
        if result.cost[-1] <= EXACT_FIT or result.iterations >= options.max_iterations:
            # at the cap, scipy's own tests on this step (without ftol's step-quality ratio) say
            # whether it would have stopped converged here anyway
            last["converged"] = old_cost - cost < options.ftol * old_cost or \
                step < options.xtol * (options.xtol + x_norm)
            raise StopIteration                           # scipy ≥ 1.16: ends with status −2

    out = least_squares(lambda d: fun(to_z(d)), np.zeros_like(z0), jac=lambda d, *_: jac(to_z(d)) * radius,
                        method="trf", tr_solver="exact", x_scale=1.0,
                        xtol=options.xtol, ftol=options.ftol, gtol=options.gtol * radius,   # gtol on ∂E/∂z
                        max_nfev=options.max_iterations * MAX_EVALUATIONS_PER_ITERATION, callback=on_step)
    values, sols = cache[to_z(out.x).tobytes()]
    if not np.allclose(result.parameters[-1], values, rtol=0, atol=0):
        result.solutions = sols
        record(values, sols)
    exact = out.status == -2 and result.cost[-1] <= EXACT_FIT
    plateau = out.status == -2 and last["plateau"]
    converged_at_cap = out.status == -2 and not exact and not plateau and last["converged"]
    result.success = bool(out.status > 0 or exact or plateau or converged_at_cap) and np.all(np.abs(out.fun) < FAILED_RESIDUAL)
    if exact:
        result.message = f"exact fit: cost {result.cost[-1]:.2e} ≤ {EXACT_FIT:g}"
    elif plateau:
        result.message = _plateau_message(result.cost, options.cost_rtol)
    elif converged_at_cap:
        result.message = f"ftol or xtol met at the iteration limit ({options.max_iterations})"
    elif out.status == -2:
        result.message = f"iteration limit ({options.max_iterations})"
    else:
        result.message = out.message


def _plateau_message(cost, cost_rtol):
    return (f"relative cost decrease {(cost[-2] - cost[-1]) / cost[-2]:.2e} below cost_rtol = {cost_rtol:g} "
            f"(E = {cost[-1]:.3e})")


class _Point:
    """The ``x`` of an intermediate result, mapped back to the log/logit variables."""

    def __init__(self, x):
        self.x = x


def _gauss_newton(mm, target, sqrt_w, initial, solutions, options, result, record, warm):
    result.success = False                      # until this run (a restart too) meets ε_m
    values, sols = np.array(initial, float), solutions
    cost = result.cost[-1]
    while result.iterations < options.max_iterations:
        m = mm.measure(sols) / target
        J = sqrt_w[..., None] * relative_jacobian(mm, values, sols, options, warm) * values / target[..., None]
        step, *_ = np.linalg.lstsq(J.reshape(target.size, -1), (sqrt_w * (1.0 - m)).ravel(), rcond=None)
        for _halving in range(12):             # safeguard: keep Λ admissible and solvable
            trial = values * (1.0 + step)
            try:
                if np.all(trial > 0) and trial[1] < trial[0]:
                    trial_sols = mm.solve(trial, warm, jacobian=options.jacobian == "implicit")
                    warm.remember(trial_sols, trial)
                    break
            except (SolveError, ParameterError) as err:
                result.failed_solves += 1
                log.info("gauss-newton: halving, forward solve failed (%s)", err)
            step = 0.5 * step
        else:
            result.message = "no admissible Gauss-Newton step"
            return
        trial_cost = float(np.sum((sqrt_w * (mm.measure(trial_sols) / target - 1.0)) ** 2))
        if trial_cost > cost and not options.fixed_iterations:
            # the paper's ε_m test fires here too, but this is no convergence; the step is not
            # taken, so the estimate is the best iterate, not the worse trial point
            warm.remember(result.solutions or sols, values)
            result.message = (f"the Gauss–Newton step raised the cost ({cost:.3e} → {trial_cost:.3e}): step "
                              f"rejected, the best iterate (iteration {len(result.cost) - 1}) is the estimate")
            return
        values, sols = trial, trial_sols
        result.solutions = sols
        record(values, sols)
        result.iterations += 1
        decrease = cost - result.cost[-1]
        cost = result.cost[-1]
        if options.fixed_iterations:
            continue
        if decrease < options.cost_tol:
            result.success = True
            result.message = f"cost decrease below ε_m = {options.cost_tol:g}"
            return
        if decrease < options.cost_rtol * (cost + decrease):
            result.success = True
            result.message = _plateau_message(result.cost, options.cost_rtol)
            return
    result.message = (f"fixed iteration count ({options.max_iterations}) done; ε_m not tested"
                      if options.fixed_iterations else f"iteration limit ({options.max_iterations})")
