"""Sensitivity of Λ to each measurement (paper §5.2): finite ±10 % and linearised."""

from __future__ import annotations

import logging

import numpy as np
import xarray as xr

from breastcore.forward.parallel import fork_map
from breastcore.inverse.identify import identify
from breastcore.inverse.uncertainty import conditioning
from breastcore.io.datasets import _var, provenance
from breastcore.model.parameters import IDENTIFIED
from breastcore.problem import ProblemSpec

log = logging.getLogger(__name__)


def finite_sensitivity(mm, target, estimate, options, delta=0.10, processes=1):
    r"""The paper's matrix ``(Λ_j(m_i+) − Λ_j(m_i−)) / (Λ_j · 2δ)``, shape ``(6, n)``.

    Each ``m_i±`` multiplies one measurement by ``1 ± δ``; Λ is re-identified from
    the estimate with the same options, each re-identification warm-started from the
    equilibria at the estimate (so that none depends on the ones before it, and the
    result is the same for any ``processes``, the number of forked workers).

    Returns
    -------
    S : (6, n) array
        NaN in the column of a measurement whose re-identification failed (a forward
        solve error at its start, or LM/Gauss–Newton ending without converging for
        another reason than its iteration limit).
    failures : int
        Measurements whose column is NaN.
    limited : int
        Re-identifications (of the 2n) that stopped at ``options.max_iterations``:
        their estimate after that many iterations is used, as in the paper's
        fixed-iteration runs.
    """
    values = np.asarray(target.values, float)
    estimate = np.asarray(estimate, float)
    n = values.size
    anchor = mm.solve(estimate)

    def reidentify(task):
        i, end = divmod(task, 2)
        log.info("finite sensitivity: re-identification %d of %d (measurement %d × %g)", task + 1, 2 * n, i,
                 (1.0 + delta, 1.0 - delta)[end])
        perturbed = values.copy().ravel()
        perturbed[i] *= (1.0 + delta, 1.0 - delta)[end]
        try:
            warm = mm.warm_starts()
            warm.remember(anchor, estimate)
            res = identify(mm, perturbed.reshape(values.shape), estimate, options, target.weights, warm=warm)
        except Exception:  # noqa: BLE001 — a failed solve: recorded, never fatal
            return None, False
        limited = res.iterations >= options.max_iterations and not res.success
        return (res.estimate if res.success or limited else None), limited

    outcomes = fork_map(reidentify, 2 * n, processes, after_fork=mm.model.after_fork)
    S = np.full((len(IDENTIFIED), n), np.nan)
    failures = 0
    for i in range(n):
        plus, minus = outcomes[2 * i][0], outcomes[2 * i + 1][0]
        if plus is None or minus is None:
            failures += 1
            continue
        S[:, i] = (plus - minus) / (estimate * 2.0 * delta)
    return S, failures, sum(limited for _, limited in outcomes)


def sensitivity_dataset(identification: xr.Dataset, finite, linear, failures, delta, config_hash=None,
                        limited=0):
    """Both matrices, their difference, rank and condition number.

    The identification's problem spec is carried over (attribute ``problem``): the
    finite matrix was computed by re-identifying exactly that problem.
    """
    postures = identification["posture"].values
    quantities = identification["quantity"].values
    labels = np.array([f"{p}:{q}" for p in postures for q in quantities])
    _, rank_lin, cond_lin = conditioning(linear)
    data = {
        "linearised": _var(("parameter", "measurement"), linear, "1",
                           "relative sensitivity ∂ln Λ_j/∂ln m_i, (JᵀWJ)⁻¹JᵀW"),
        "estimate": identification["estimate"].variable,
    }
    attrs = dict(delta=delta, linearised_rank=rank_lin, linearised_condition=cond_lin)
    if finite is not None:
        data["finite"] = _var(("parameter", "measurement"), finite, "1",
                              f"relative sensitivity by re-identification with m_i × (1 ± {delta})")
        data["difference"] = _var(("parameter", "measurement"), finite - linear, "1", "finite − linearised")
        ok = np.all(np.isfinite(finite), axis=0)
        _, rank_fin, cond_fin = conditioning(finite[:, ok]) if ok.any() else (None, 0, np.inf)
        attrs.update(finite_rank=rank_fin, finite_condition=cond_fin, finite_failures=failures,
                     finite_iteration_limited=limited)
    coords = {
        "parameter": identification["parameter"].variable,
        "measurement": _var(("measurement",), labels, "1", "posture:quantity"),
    }
    ds = xr.Dataset(data, coords=coords)
    ds.attrs = provenance("sensitivity", dict(zip(IDENTIFIED, identification["estimate"].values.tolist())),
                          config_hash, title="breastcore sensitivity of Λ to the measurements",
                          **ProblemSpec.from_dataset(identification).attrs(), **attrs)
    return ds
