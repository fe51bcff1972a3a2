"""Sensitivity of Λ to each measurement (paper §5.2): finite ±10 % and linearised."""

from __future__ import annotations

import numpy as np
import xarray as xr

from .datasets import _var, provenance
from .identify import identify
from .parameters import IDENTIFIED
from .uncertainty import conditioning


def finite_sensitivity(mm, target, estimate, options, delta=0.10):
    r"""The paper's matrix ``(Λ_j(m_i+) − Λ_j(m_i−)) / (Λ_j · 2δ)``, shape ``(6, n)``.

    Each ``m_i±`` multiplies one measurement by ``1 ± δ``; Λ is re-identified from
    the estimate (warm start), with the same options. Failed re-identifications
    leave NaN in their column and are counted in the second return value.
    """
    values = np.asarray(target.values, float)
    n = values.size
    S = np.full((len(IDENTIFIED), n), np.nan)
    failures = 0
    for i in range(n):
        ends = []
        for sign in (1.0, -1.0):
            perturbed = values.copy().ravel()
            perturbed[i] *= 1.0 + sign * delta
            try:
                res = identify(mm, perturbed.reshape(values.shape), estimate, options, target.weights)
                ends.append(res.estimate if res.success else None)
            except Exception:  # noqa: BLE001 — a failed solve: recorded, never fatal
                ends.append(None)
        if any(e is None for e in ends):
            failures += 1
            continue
        S[:, i] = (ends[0] - ends[1]) / (np.asarray(estimate) * 2.0 * delta)
    return S, failures


def sensitivity_dataset(identification: xr.Dataset, finite, linear, failures, delta, config_hash=None):
    """Both matrices, their difference, rank and condition number."""
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
        attrs.update(finite_rank=rank_fin, finite_condition=cond_fin, finite_failures=failures)
    coords = {
        "parameter": identification["parameter"].variable,
        "measurement": _var(("measurement",), labels, "1", "posture:quantity"),
    }
    ds = xr.Dataset(data, coords=coords)
    ds.attrs = provenance("sensitivity", dict(zip(IDENTIFIED, identification["estimate"].values.tolist())),
                          config_hash, title="breastcore sensitivity of Λ to the measurements", **attrs)
    return ds
