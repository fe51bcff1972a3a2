"""The paper's Gauss–Newton iteration on ``M(Λ)``.

Forward-difference Jacobian with relative step ``ε``, the step ``ΔΛ/Λ = (JᵀJ)⁻¹ Jᵀ (1 − m)``
(the paper's equation carries a stray factor 2, which would double the Gauss–Newton step),
stopped when ``E(Λⁿ) − E(Λⁿ⁺¹) < ε_m``.
"""

from __future__ import annotations

import numpy as np

from breastcore.forward.records import SolveError
from breastcore.inverse.history import log
from breastcore.inverse.lm import plateau_message
from breastcore.model.parameters import ParameterError

#: Halvings of a Gauss–Newton step before the run gives up on finding an admissible one.
MAX_HALVINGS = 12


def _admissible_step(mm, values, step, options, run, warm):
    """``(trial Λ, its equilibria)`` along ``step``, halved until Λ is admissible and solvable; None if never."""
    for _halving in range(MAX_HALVINGS):
        trial = values * (1.0 + step)
        try:
            if np.all(trial > 0) and trial[1] < trial[0]:
                trial_sols = mm.solve(trial, warm, jacobian=options.jacobian == "implicit")
                warm.remember(trial_sols, trial)
                return trial, trial_sols
        except (SolveError, ParameterError) as err:
            run.failed_solves += 1
            log.info("gauss-newton: halving, forward solve failed (%s)", err)
        step = 0.5 * step
    return None


def gauss_newton(mm, target, sqrt_w, initial, solutions, options, run, warm, jacobian):
    """Run Gauss–Newton from ``initial`` (equilibria ``solutions``), recording into ``run``.

    ``jacobian`` as :func:`~breastcore.inverse.lm.levenberg_marquardt`'s. Sets ``run.success``
    and ``run.message``.
    """
    run.success = False                         # until this run (a restart too) meets ε_m
    values, sols = np.array(initial, float), solutions
    cost = run.cost[-1]
    while run.iterations < options.max_iterations:
        m = mm.measure(sols) / target
        J = sqrt_w[..., None] * jacobian(mm, values, sols, options, warm) * values / target[..., None]
        step, *_ = np.linalg.lstsq(J.reshape(target.size, -1), (sqrt_w * (1.0 - m)).ravel(), rcond=None)
        trial = _admissible_step(mm, values, step, options, run, warm)
        if trial is None:
            run.message = "no admissible Gauss-Newton step"
            return
        trial, trial_sols = trial
        trial_cost = float(np.sum((sqrt_w * (mm.measure(trial_sols) / target - 1.0)) ** 2))
        if trial_cost > cost and not options.fixed_iterations:
            # the paper's ε_m test fires here too, but this is no convergence; the step is not
            # taken, so the estimate is the best iterate, not the worse trial point
            warm.remember(run.solutions or sols, values)
            run.message = (f"the Gauss–Newton step raised the cost ({cost:.3e} → {trial_cost:.3e}): step "
                           f"rejected, the best iterate (iteration {len(run.cost) - 1}) is the estimate")
            return
        values, sols = trial, trial_sols
        run.solutions = sols
        run.record(values, sols)
        run.iterations += 1
        decrease = cost - run.cost[-1]
        cost = run.cost[-1]
        if options.fixed_iterations:
            continue
        if decrease < options.cost_tol:
            run.success = True
            run.message = f"cost decrease below ε_m = {options.cost_tol:g}"
            return
        if decrease < options.cost_rtol * (cost + decrease):
            run.success = True
            run.message = plateau_message(run.cost, options.cost_rtol)
            return
    run.message = (f"fixed iteration count ({options.max_iterations}) done; ε_m not tested"
                   if options.fixed_iterations else f"iteration limit ({options.max_iterations})")
