"""Levenberg–Marquardt on ``M(Λ)``: scipy's trust-region ``trf`` in the unconstrained variables.

``scipy.optimize.least_squares`` (``method="trf"``, exact subproblem) minimises the weighted
relative residuals in ``d = (z − z₀)/r``, ``z`` the variables of
:mod:`~breastcore.inverse.transforms` and ``r`` the first trust radius. A step whose forward
solve fails returns residuals larger than those of the current point (at least
:data:`FAILED_RESIDUAL` each), so it is rejected and the trust region shrinks: a failed solve
never ends the run, and is never accepted, however badly the current point fits.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from breastcore.forward.records import SolveError
from breastcore.inverse.history import log
from breastcore.inverse.transforms import from_unconstrained, to_unconstrained, unconstrained_chain
from breastcore.model.parameters import ParameterError

#: Least residual returned for a Λ whose forward solve fails (each entry; more where the current
#: point's cost is higher, e.g. measurements entered in the wrong unit, ~1e6 relative residuals).
FAILED_RESIDUAL = 1e3
#: LM's cap on residual evaluations (trial points, accepted or not) per allowed iteration.
MAX_EVALUATIONS_PER_ITERATION = 3
#: A cost at which the data are fit to round-off (rms relative residual ~3e-9 over 15
#: measurements): LM stops there, and a branch drift found at such an estimate is not chased.
EXACT_FIT = 1e-16


class _Residuals:
    """The residuals, Jacobian and per-iteration callback that scipy's ``trf`` calls, in ``d``.

    Every evaluated point is kept with its Λ and equilibria (``evaluations``): scipy asks for
    the Jacobian and reports an accepted step at points it has evaluated, and returns one.
    """

    def __init__(self, mm, target, sqrt_w, initial, solutions, options, run, warm, jacobian):
        self.mm, self.target, self.sqrt_w, self.options, self.run, self.warm = mm, target, sqrt_w, options, run, warm
        self.relative_jacobian = jacobian
        self.z0, self.radius = to_unconstrained(initial), options.initial_trust_radius
        self.evaluations = [(np.zeros_like(self.z0), np.asarray(initial, float), solutions)]
        self.last_x, self.last_cost = np.zeros_like(self.z0), 0.5 * run.cost[-1]
        self.plateau = False                     # stopped by cost_rtol
        self.converged = False                   # stopped at an exact fit or the cap, scipy's tests met

    def at(self, d):
        """``(Λ, equilibria)`` of an evaluated point ``d``."""
        for x, values, sols in reversed(self.evaluations):
            if np.array_equal(x, d):
                return values, sols
        raise KeyError("scipy asked about a point it has not evaluated")

    def residuals(self, d):
        if not np.any(d):                                 # the start: its equilibria are known
            return (self.sqrt_w * (self.mm.measure(self.evaluations[0][2]) / self.target - 1.0)).ravel()
        values = from_unconstrained(self.z0 + self.radius * d)
        try:
            sols = self.mm.solve(values, self.warm, jacobian=self.options.jacobian == "implicit")
        except (SolveError, ParameterError) as err:
            self.run.failed_solves += 1
            log.info("identify: step rejected, forward solve failed (%s)", err)
            # above the current point's cost 0.5 Σ r² (scipy's), so that scipy rejects the step
            return np.full(self.target.size, max(FAILED_RESIDUAL, 10.0 * np.sqrt(2.0 * self.last_cost)))
        self.evaluations.append((np.array(d, float), values, sols))
        return (self.sqrt_w * (self.mm.measure(sols) / self.target - 1.0)).ravel()

    def jacobian(self, d, *_):
        values, sols = self.at(d)
        self.warm.remember(sols, values)                  # accepted point: warm start from here
        dM = self.relative_jacobian(self.mm, values, sols, self.options, self.warm)
        J = (self.sqrt_w[..., None] * dM / self.target[..., None]).reshape(self.target.size, -1)
        return J @ unconstrained_chain(values) * self.radius

    def on_step(self, intermediate_result):
        """scipy's callback after each iteration: record an accepted step, stop where we stop."""
        x, cost = intermediate_result.x, float(intermediate_result["cost"])
        if np.array_equal(x, self.last_x):    # scipy calls back after a rejected last step too
            return
        step, x_norm, old_cost = np.linalg.norm(x - self.last_x), np.linalg.norm(self.last_x), self.last_cost
        self.last_x, self.last_cost = x.copy(), cost
        values, sols = self.at(x)
        self.run.solutions = sols
        self.run.record(values, sols)
        self.run.iterations += 1
        options = self.options
        if old_cost - cost < options.cost_rtol * old_cost:
            self.plateau = True
            raise StopIteration                           # scipy's protocol (≥ 1.16): ends with status −2
        if self.run.cost[-1] <= EXACT_FIT or self.run.iterations >= options.max_iterations:
            # at the cap, scipy's own tests on this step (without ftol's step-quality ratio) say
            # whether it would have stopped converged here anyway
            self.converged = old_cost - cost < options.ftol * old_cost or \
                step < options.xtol * (options.xtol + x_norm)
            raise StopIteration


def levenberg_marquardt(mm, target, sqrt_w, initial, solutions, options, run, warm, jacobian):
    """Run LM from ``initial`` (equilibria ``solutions``), recording into ``run``.

    ``jacobian(mm, values, solutions, options, warm)`` gives ``∂M/∂Λ`` (posture, quantity, 6).
    Sets ``run.success`` and ``run.message``.
    """
    problem = _Residuals(mm, target, sqrt_w, initial, solutions, options, run, warm, jacobian)
    out = least_squares(problem.residuals, np.zeros_like(problem.z0), jac=problem.jacobian,
                        method="trf", tr_solver="exact", x_scale=1.0,
                        xtol=options.xtol, ftol=options.ftol, gtol=options.gtol * problem.radius,  # on ∂E/∂z
                        max_nfev=options.max_iterations * MAX_EVALUATIONS_PER_ITERATION, callback=problem.on_step)
    values, sols = problem.at(out.x)
    if not np.allclose(run.parameters[-1], values, rtol=0, atol=0):
        run.solutions = sols
        run.record(values, sols)
    stopped = out.status == -2                            # by on_step
    exact = stopped and run.cost[-1] <= EXACT_FIT
    plateau = stopped and problem.plateau
    converged_at_cap = stopped and not exact and not plateau and problem.converged
    # out.x is a point whose solve succeeded: scipy accepts no failed one (problem.at found it)
    run.success = bool(out.status > 0 or exact or plateau or converged_at_cap)
    if exact:
        run.message = f"exact fit: cost {run.cost[-1]:.2e} ≤ {EXACT_FIT:g}"
    elif plateau:
        run.message = plateau_message(run.cost, options.cost_rtol)
    elif converged_at_cap:
        run.message = f"ftol or xtol met at the iteration limit ({options.max_iterations})"
    elif stopped:
        run.message = f"iteration limit ({options.max_iterations})"
    else:
        run.message = out.message


def plateau_message(cost, cost_rtol):
    """The message of a run stopped by ``cost_rtol``."""
    return (f"relative cost decrease {(cost[-2] - cost[-1]) / cost[-2]:.2e} below cost_rtol = {cost_rtol:g} "
            f"(E = {cost[-1]:.3e})")
