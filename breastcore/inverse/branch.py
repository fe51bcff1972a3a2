"""The branch check: is the estimate's warm-started equilibrium the one a cold solve gives?"""

from __future__ import annotations

import numpy as np

from breastcore.forward.records import SolveError
from breastcore.inverse.history import log
from breastcore.inverse.lm import EXACT_FIT
from breastcore.model.parameters import ParameterError

#: Largest relative difference between warm- and cold-started measurements at the estimate.
BRANCH_TOL = 1e-6
#: Restarts after a branch drift (each re-anchored on the cold equilibria, then warm again).
BRANCH_RESTARTS = 2


def check_branch(mm, target, sqrt_w, options, run, method, warm_starts):
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
    that remains is recorded in ``run.branch_drift`` (and logged). The history
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

    ``method`` is the identification's method (:func:`~breastcore.inverse.lm.levenberg_marquardt`
    or :func:`~breastcore.inverse.gauss_newton.gauss_newton` with its Jacobian bound), called as
    ``method(mm, target, sqrt_w, initial, solutions, options, run, warm)``.
    """
    for attempt in range(BRANCH_RESTARTS + 1):
        values = np.array(run.parameters[-1], float)
        warm = run.solutions if run.solutions is not None else mm.solve(values, warm_starts)
        if mm.solved_cold(warm):                        # the last step was solved cold: nothing to check
            run.branch_drift = 0.0
            return
        try:
            cold = mm.solve(values)
        except (SolveError, ParameterError) as err:
            log.warning("identify: the cold re-solve at the estimate failed (%s); branch not checked", err)
            return
        run.branch_drift = float(np.max(np.abs(mm.measure(warm) / mm.measure(cold) - 1.0)))
        if run.branch_drift <= BRANCH_TOL or not run.success:    # a failed run is not extended
            return
        if _kept(mm, target, sqrt_w, options, run, warm, cold, attempt):
            return
        log.warning("identify: warm starts drifted to another equilibrium branch (max |ΔM/M| = %.2e); "
                    "continuing from the cold equilibria", run.branch_drift)
        run.branch_restarts += 1
        warm_starts.remember(cold, values)
        run.solutions = cold
        run.record(values, cold)
        method(mm, target, sqrt_w, values, cold, options, run, warm_starts)


def _kept(mm, target, sqrt_w, options, run, warm, cold, attempt):
    """Whether a drifted estimate is kept (logged why) rather than continued from ``cold``."""
    drift_rms = float(np.sqrt(np.mean((sqrt_w * (mm.measure(warm) / mm.measure(cold) - 1.0)) ** 2)))
    residual = float(np.sqrt(run.cost[-1] / target.size))
    if drift_rms <= residual:
        log.info("identify: warm and cold equilibria differ by %.2e (weighted RMS %.2e) at the estimate, "
                 "no more than the fit's weighted RMS residual %.2e; kept", run.branch_drift, drift_rms, residual)
        return True
    if run.iterations >= options.max_iterations:
        log.warning("identify: warm and cold equilibria differ by %.2e at the estimate; no iterations left "
                    "to continue from the cold ones", run.branch_drift)
        return True
    if run.cost[-1] <= EXACT_FIT:                   # the warm equilibria fit the data exactly
        log.info("identify: warm and cold equilibria differ by %.2e at the estimate; the warm ones "
                 "fit the data (E = %.2e), kept", run.branch_drift, run.cost[-1])
        return True
    if attempt == BRANCH_RESTARTS:
        log.warning("identify: warm and cold equilibria still differ by %.2e at the estimate after %d "
                    "restarts; the estimate fits the warm ones", run.branch_drift, attempt)
        return True
    return False
