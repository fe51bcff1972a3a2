"""An identification as a clinician reads it: the estimate with its 95 % intervals, the fit
verdict, and the measurements against the model's, in clinical units (mm, cm², ml).

Used by ``breastcore show`` on a patient summary or an identification dataset.
"""

from __future__ import annotations

import json

from breastcore.inverse.uncertainty import SEEN, limit_note
from breastcore.io.patient import DEFAULT_UNITS, KIND, UNIT_FACTORS


def _clinical(quantity):
    unit = DEFAULT_UNITS[quantity]
    return unit.replace("2", "²"), 1.0 / UNIT_FACTORS[KIND[quantity]][unit]


#: Clinical unit and factor from SI of each measured quantity: the patient files' default units.
QUANTITY_UNITS = {quantity: _clinical(quantity) for quantity in DEFAULT_UNITS}
#: Clinical unit and factor from SI of each identified parameter.
PARAMETER_UNITS = {"R": ("mm", 1e3), "H": ("mm", 1e3), "lambda_breast": ("Pa", 1.0), "mu_breast": ("Pa", 1.0),
                   "lambda_skin": ("Pa", 1.0), "mu_skin": ("Pa", 1.0)}


def measured_and_fitted(ds):
    """``(measured, fitted)``, ``(posture, quantity)`` arrays in SI, of a patient summary
    (``measured``, ``fitted``) or an identification dataset (``target`` and the last
    ``measurement_error``); None when the dataset has neither."""
    if "measured" in ds and "fitted" in ds:
        return ds["measured"].values, ds["fitted"].values
    if "target" in ds and "measurement_error" in ds:
        target = ds["target"].values
        return target, target * (1.0 + ds["measurement_error"].values[-1])
    return None


def estimate_rows(ds) -> list:
    """Per parameter: ``(name, estimate, unit, interval)``, the estimate in clinical units and
    ``interval`` either ``(low, high)`` or the reason there is none (a str; for an unseen parameter,
    :func:`~breastcore.inverse.uncertainty.limit_note`)."""
    rows = []
    for i, name in enumerate(str(p) for p in ds["parameter"].values):
        unit, factor = PARAMETER_UNITS.get(name, ("", 1.0))
        value = float(ds["estimate"].values[i]) * factor
        limit = int(ds["limit"].values[i]) if "limit" in ds else SEEN        # datasets before the flag: none
        if limit != SEEN:
            interval = limit_note(limit, value, unit)
        elif int(ds["determined"].values[i]):
            interval = tuple(float(ds[k].values[i]) * factor for k in ("interval_low", "interval_high"))
        else:
            decades = float(ds["interval_decades"].values[i]) if "interval_decades" in ds else float("nan")
            span = "over 10 decades" if decades > 10 else f"{decades:.2g} decades"
            interval = f"not determined: its 95 % interval spans {span}"
        rows.append((name, value, unit, interval))
    return rows


def estimate_lines(ds) -> list:
    """One line per parameter: the estimate and its 95 % interval, or why there is none."""
    lines = ["  estimate (95 % intervals, linearised under the identification's noise model):"]
    for name, value, unit, interval in estimate_rows(ds):
        why = interval if isinstance(interval, str) else f"95 %: {interval[0]:.4g} … {interval[1]:.4g} {unit}"
        lines.append(f"      {name:<14} {value:>10.4g} {unit:<3}  {why}")
    return lines


def fit_rows(ds) -> list:
    """Per posture and quantity: ``(posture, quantity, unit, measured, fitted, worst)`` in clinical
    units, ``worst`` whether the identification named it among its worst-fitted; [] without a fit."""
    pair = measured_and_fitted(ds)
    if pair is None:
        return []
    measured, fitted = pair
    worst = set(json.loads(ds.attrs.get("worst_measurements", "[]") or "[]"))
    rows = []
    for i, posture in enumerate(str(p) for p in ds["posture"].values):
        for j, quantity in enumerate(str(q) for q in ds["quantity"].values):
            unit, factor = QUANTITY_UNITS.get(quantity, ("SI", 1.0))
            rows.append((posture, quantity, unit, measured[i, j] * factor, fitted[i, j] * factor,
                         f"{posture}:{quantity}" in worst))
    return rows


def fit_lines(ds) -> list:
    """The measured values beside the fitted ones, per posture and quantity, in clinical units."""
    rows = fit_rows(ds)
    if not rows:
        return []
    lines = ["  measured against fitted (the model at the estimate):",
             f"      {'posture':<10} {'quantity':<20} {'measured':>10} {'fitted':>10} {'difference':>11}"]
    for posture, quantity, unit, m, f, worst in rows:
        flag = "  (among the worst)" if worst else ""
        lines.append(f"      {posture:<10} {quantity + ' (' + unit + ')':<20} {m:>10.4g} {f:>10.4g} "
                     f"{100.0 * (f / m - 1.0):>+10.2f} %{flag}")
    return lines


def clinical_lines(ds, pictures=()) -> list:
    """The block ``show`` prints first for a patient: verdict, estimate, fit, pictures."""
    lines = []
    if "verdict" in ds.attrs:
        lines.append(f"  fit verdict: {ds.attrs['verdict']}: {ds.attrs.get('verdict_message', '')}")
    if "estimate" in ds and "determined" in ds:
        lines += estimate_lines(ds)
    lines += fit_lines(ds)
    if pictures:
        lines.append("  shape pictures: " + ", ".join(str(p) for p in pictures))
    return lines

