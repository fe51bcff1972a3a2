"""Per-scene summary datasets and report tables."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import xarray as xr

from breastcore.inverse.uncertainty import DETERMINED_FACTOR, SEEN, limit_note
from breastcore.inverse.verdict import VERDICTS
from breastcore.io.datasets import _var, open_dataset, provenance
from breastcore.io.solution import DIAGNOSTICS
from breastcore.io.targets import measure_solution
from breastcore.model.parameters import IDENTIFIED, PARAMETER_INFO


def synthetic_summary(runs, paths, name, config_hash=None, tables=(), sensitivity=(), paper_table="none",
                      truth=None, level_solutions=None, *, truth_mesh) -> xr.Dataset:
    """One row per identification run: mesh, offset, errors, cost, iterations, time, success.

    ``tables`` names the extra results-page tables of the scene (``levels``,
    ``measurements``, ``evolution``); it is stored as the attribute ``tables``, and
    ``paper_table`` (the paper's table to print beside, see
    :mod:`breastcore.report.paper_values`) as ``paper_table``. ``sensitivity``: the
    scene's sensitivity datasets; the first one's matrices are copied in as
    ``sensitivity_*(parameter, measurement)``, with their ranks and conditions.
    ``truth`` and ``level_solutions`` (``{level: path}``): the truth solution and a
    solution at the same parameters on each level; with both, the summary carries
    ``discretisation_error(level, posture, quantity) = M_level/M_truth − 1``. The truth's
    parameters become the summary's ``parameters`` attribute. ``truth_mesh`` (attribute
    of the same name, required: no default level) is the level the data were solved on, or
    ``"same"`` when each level identifies data solved on itself.
    """
    rows = [open_dataset(p) for p in paths]
    rel = np.array([ds["relative_error"].values for ds in rows])
    n = rows[0].sizes["posture"] * rows[0].sizes["quantity"]
    data = {
        "method": _var(("run",), np.array([r.get("method", "lm-implicit") for r in runs]), "1",
                       "identification method label"),
        "mesh": _var(("run",), np.array([r["mesh"] for r in runs]), "1", "mesh level identified on"),
        "measurement_residual": _var(("run",), np.array([np.sqrt(ds["cost"].values[-1] / n) for ds in rows]), "1",
                                     "RMS relative measurement residual sqrt(E/n)"),
        "offset": _var(("run",), np.array([r["offset"] for r in runs]), "1", "initial-guess distance (relative)"),
        "relative_error": _var(("run", "parameter"), rel, "1", "estimate / truth − 1"),
        "mean_abs_error": _var(("run",), np.abs(rel).mean(axis=1), "1", "mean |relative error| over the six"),
        "cost": _var(("run",), np.array([ds["cost"].values[-1] for ds in rows]), "1", "final cost E"),
        "iterations": _var(("run",), np.array([int(ds.attrs.get("iterations", ds.sizes["iteration"] - 1))
                                               for ds in rows]), "1", "accepted iterations"),
        "wall_time": _var(("run",), np.array([ds["wall_time"].values[-1] for ds in rows]), "s", "identification time"),
        "success": _var(("run",), np.array([int(ds.attrs["success"]) for ds in rows]), "1",
                        "1 if the optimiser met its stopping test (what the estimate is worth: verdict)"),
        "verdict": _var(("run",), np.array([ds.attrs["verdict"] for ds in rows]), "1",
                        "fit verdict: consistent, misfit or not_converged (breastcore.inverse.verdict)"),
        "determined": _var(("run", "parameter"), np.array([ds["determined"].values for ds in rows]), "1",
                           f"1 if the parameter's 95 % interval spans at most a factor {DETERMINED_FACTOR:g}"),
        "covered": _var(("run", "parameter"),
                        np.array([((ds["interval_low"] <= ds["truth"]) & (ds["truth"] <= ds["interval_high"])).values
                                  for ds in rows]).astype(np.int8), "1",
                        "1 if the 95 % interval contains the truth (0 where it does not, or is not determined)"),
        "forward_solves": _var(("run",), np.array([int(ds.attrs["forward_solves"]) for ds in rows]), "1",
                               "forward solves (all postures counted)"),
        "final_measurement_error": _var(("run", "posture", "quantity"),
                                        np.array([ds["measurement_error"].values[-1] for ds in rows]), "1",
                                        "relative measurement error M(Λ̂)/M̄ − 1 at the estimate"),
        "relative_error_history": _var(("run", "iteration", "parameter"), _histories(rows), "1",
                                       "Λ/truth − 1 per recorded iteration (0 = initial guess); NaN after the "
                                       "run's last iteration"),
    }
    coords = {"parameter": _var(("parameter",), np.array(IDENTIFIED), "1", "identified parameter"),
              "identification": _var(("run",), np.array(paths), "1", "identification dataset"),
              "posture": rows[0]["posture"].variable, "quantity": rows[0]["quantity"].variable}
    if truth is not None and level_solutions:
        data["discretisation_error"], coords["level"] = discretisation_error(truth, level_solutions,
                                                                             rows[0].attrs["measurement_set"])
    extra = {}
    if sensitivity:
        sens = open_dataset(sensitivity[0])
        coords["measurement"] = sens["measurement"].variable
        for key in ("linearised", "finite", "difference"):
            if key in sens:
                data[f"sensitivity_{key}"] = sens[key].variable
        extra = {f"sensitivity_{k}": v for k, v in sens.attrs.items()
                 if k.startswith(("linearised_", "finite_")) or k == "delta"}
        extra["sensitivity_mesh"] = runs[0]["mesh"]        # the plan analyses the scene's first run
    ds = xr.Dataset(data, coords=coords)
    truth_parameters = json.loads(open_dataset(truth).attrs.get("parameters", "{}")) if truth else None
    ds.attrs = provenance("scene", truth_parameters, config_hash, scene=name, scene_kind="synthetic",
                          tables=",".join(tables), truth_mesh=truth_mesh,
                          paper_table=paper_table,
                          title=f"synthetic identification study {name}", **extra)
    return ds


def _histories(rows):
    """``(run, iteration, parameter)`` array of ``Λ/truth − 1`` per recorded iteration, NaN-padded."""
    length = max(ds.sizes["iteration"] for ds in rows)
    out = np.full((len(rows), length, len(IDENTIFIED)), np.nan)
    for i, ds in enumerate(rows):
        out[i, :ds.sizes["iteration"]] = ds["parameters"].values / ds["truth"].values - 1.0
    return out


def discretisation_error(truth, level_solutions, measurement_set):
    """``(variable, level coordinate)``: each level's measurements at the truth's Λ over the truth's, minus 1.

    The paper's Table 2 residual is the mean of its squares: the discretisation gap
    of a level, with no identification involved. A posture whose solve (on the level
    or on the truth mesh) did not converge gives NaN, never a number.
    """
    def measured(path):
        with open_dataset(path) as ds:
            values = measure_solution(ds, measurement_set)[0].values
            return np.where(ds["converged"].values.astype(bool)[:, None], values, np.nan)

    reference = measured(truth)
    gaps = [measured(path) / reference - 1.0 for path in level_solutions.values()]
    return (_var(("level", "posture", "quantity"), np.array(gaps), "1",
                 "M_level(Λ̄)/M_truth(Λ̄) − 1: measurements at the truth parameters on each level against the "
                 "truth mesh's"),
            _var(("level",), np.array(list(level_solutions)), "1", "mesh level"))


def error_table(summary: xr.Dataset) -> pd.DataFrame:
    """Mean |relative error| in % per mesh and offset, per parameter (paper's Table 1 layout),
    with the number of runs of each fit verdict (consistent, misfit, not_converged)."""
    df = pd.DataFrame(np.abs(summary["relative_error"].values) * 100, columns=IDENTIFIED)
    df["mean"] = df[list(IDENTIFIED)].mean(axis=1)
    df["residual"] = summary["measurement_residual"].values
    df["method"], df["mesh"], df["offset"] = summary["method"].values, summary["mesh"].values, summary["offset"].values
    df["time_s"], df["iterations"] = summary["wall_time"].values, summary["iterations"].values
    keys = ["method", "mesh", "offset"]
    table = df.groupby(keys, sort=False).mean().round(5)
    verdicts = pd.Series(summary["verdict"].values.astype(str))
    for verdict in VERDICTS:                                   # counts of verdicts, not of optimiser exits
        table[verdict] = (verdicts == verdict).groupby([df[k] for k in keys], sort=False).sum().values
    return table


def error_table_with_units(summary: xr.Dataset) -> pd.DataFrame:
    """:func:`error_table` with a unit in every column name (``parameter_errors.csv``): errors
    and the residual in %, the wall time in s, the iterations and verdicts as counts. The errors are
    means over the runs of ``|estimate / truth − 1|``, so the names say ``|error|``: a sign would cancel."""
    table = error_table(summary)
    table["residual"] = (table["residual"] * 100).round(5)
    names = {p: f"{p} |error| (%)" for p in IDENTIFIED}
    names.update({"mean": "mean |error| over the parameters (%)", "residual": "RMS measurement residual (%)",
                  "time_s": "wall time (s)", "iterations": "iterations (mean count)"})
    names.update({v: f"{v} (runs)" for v in VERDICTS})
    return table.rename(columns=names).rename_axis(index={"offset": "initial offset (fraction)"})


def solution_summary(path, name, kind, config_hash=None) -> xr.Dataset:
    """Diagnostics per posture of a solution or identification dataset, plus nipple displacement."""
    ds = open_dataset(path)
    nipple = int(ds["landmark_node"].sel(landmark="nipple"))
    disp = ds["position"][:, nipple] - ds["reference_position"][nipple]
    data = {"nipple_displacement": _var(("posture", "xyz"), disp.values, "m", "nipple displacement under gravity")}
    for key in DIAGNOSTICS:
        for variable in (key, "solve_" + key):
            if variable in ds and "posture" in ds[variable].dims:
                data[key] = ds[variable].variable
    verdict = {}
    if kind == "patient":
        for key in ("estimate", "interval_low", "interval_high", "interval_decades", "determined", "limit", "cost",
                    "standardised_residual"):
            if key in ds:                    # an identification from before the limit flag has none
                data[key] = ds[key].variable
        units = ds["target"].attrs["units"]
        data["measured"] = _var(("posture", "quantity"), ds["target"].values, units,
                                "measured values M̄ (units per quantity, in the order of quantity)")
        data["fitted"] = _var(("posture", "quantity"), ds["target"].values * (1.0 + ds["measurement_error"].values[-1]),
                              units, "the model's measurements at the estimate M(Λ̂) (units per quantity)")
        verdict = {k: ds.attrs[k] for k in ("verdict", "verdict_message", "worst_measurements", "input_notes",
                                            "regime_warning")}
    elif ds.attrs.get("regime_warning"):
        verdict = {"regime_warning": ds.attrs["regime_warning"]}          # a forward scene's shape warning
    if "sliding_margin" in ds:
        data["sliding_margin"] = ds["sliding_margin"].variable
    out = xr.Dataset(data, coords={k: ds[k].variable for k in ("posture", "xyz") if k in ds.coords}
                     | ({"parameter": ds["parameter"].variable} if kind == "patient" else {})
                     | ({"iteration": ds["iteration"].variable, "quantity": ds["quantity"].variable}
                        if kind == "patient" else {}))
    # the Λ that defines the scene: a forward scene's, or a patient's estimate
    out.attrs = provenance("scene", json.loads(ds.attrs.get("parameters", "{}")), config_hash, scene=name,
                           scene_kind=kind, source=str(path),
                           title=f"{kind} scene {name}", **verdict)
    return out


def record_datasets(summary: xr.Dataset, datasets) -> xr.Dataset:
    """Store the scene's lineage in ``summary.attrs["datasets"]`` (JSON list).

    ``datasets``: the stage datasets the scene is computed from, as paths relative to the
    results folder (:meth:`breastcore.pipeline.plan.Plan.scene_datasets`). With them
    ``breastcore list`` names the scenes that each shared mesh, solve or identification serves.
    """
    summary.attrs["datasets"] = json.dumps(list(datasets))
    return summary


def parameter_table(identification: xr.Dataset) -> pd.DataFrame:
    """Estimate and 95 % interval per parameter, with units, whether the data determine it, and the
    fit verdict and the input checks' notes of the identification (the same on every row)."""
    determined = identification["determined"].values.astype(bool)
    notes = "; ".join(json.loads(identification.attrs.get("input_notes", "[]"))) or "none"
    return pd.DataFrame({
        "parameter": IDENTIFIED,
        "units": [PARAMETER_INFO[p].units for p in IDENTIFIED],
        "estimate": identification["estimate"].values,
        "ci95_low": identification["interval_low"].values,
        "ci95_high": identification["interval_high"].values,
        "interval_decades": identification["interval_decades"].values,
        "determined": np.where(determined, "yes", "no: not determined by these measurements"),
        "limit": _limit_column(identification),
        "fit_verdict": identification.attrs["verdict"],
        "regime_warning": identification.attrs.get("regime_warning") or "none",
        "input_notes": notes,
    })


def _limit_column(identification) -> list:
    """Per parameter: "none (a value)", why it is a limit, or "not recorded" (a dataset from before the flag)."""
    if "limit" not in identification:
        return ["not recorded"] * len(IDENTIFIED)
    return [limit_note(code, value, PARAMETER_INFO[p].units) if code != SEEN else "none (a value)"
            for p, code, value in zip(IDENTIFIED, identification["limit"].values.astype(int),
                                      identification["estimate"].values)]


def diagnostics_table(ds: xr.Dataset) -> pd.DataFrame:
    """Solver diagnostics per posture of a solution (or identification: ``solve_*``) dataset; each
    column's heading carries its unit, ``gradient_norm (N)``, or none for a count or a ratio."""
    def heading(key):
        units = DIAGNOSTICS[key][0]
        return key if units == "1" else f"{key} ({units})"
    cols = {heading(k): ds[n].values for k in DIAGNOSTICS for n in (k, "solve_" + k)
            if n in ds and "posture" in ds[n].dims}
    return pd.DataFrame(cols, index=pd.Index(ds["posture"].values, name="posture"))


def stability_summary(paths, name, config_hash=None, guesses=()) -> xr.Dataset:
    """All cases of a stability scene in one dataset, with the outcome counts.

    ``guesses``: datasets of the identifications from extreme guesses (dimension
    ``guess``, one block per mesh level, with ``guess_mesh``).
    """
    parts = [open_dataset(p) for p in paths]
    ds = xr.concat(parts, dim="case", data_vars="all", combine_attrs="override")
    ds["mesh"] = _var(("case",), np.concatenate([[p.attrs["mesh_level"]] * p.sizes["case"] for p in parts]), "1",
                      "mesh level")
    extra = {}
    if guesses:
        runs = [open_dataset(p) for p in guesses]
        g = xr.concat(runs, dim="guess", data_vars="all", combine_attrs="override")
        g["guess_mesh"] = _var(("guess",), np.concatenate([[r.attrs["mesh_level"]] * r.sizes["guess"] for r in runs]),
                               "1", "mesh level of the identification")
        ds = xr.merge([ds, g], combine_attrs="drop_conflicts")
        outcomes = g["guess_outcome"].values
        extra["guess_outcome_counts"] = {o: int((outcomes == o).sum()) for o in dict.fromkeys(outcomes)}
    outcomes = ds["outcome"].values
    counts = {o: int((outcomes == o).sum()) for o in ("converged", "unverified", "nan", "solve_error", "crash")}
    ds.attrs = provenance("scene", None, config_hash, scene=name, scene_kind="stability", outcome_counts=counts,
                          convergence_rate=counts["converged"] / max(len(outcomes), 1),
                          title=f"stability scene {name}", **extra)
    return ds


def stability_table(ds: xr.Dataset) -> pd.DataFrame:
    """Outcome counts per value of every factor (and overall)."""
    from breastcore.studies.stability import FACTORS, OUTCOMES
    rows = []
    for factor in ("mesh", *FACTORS):
        for value in dict.fromkeys(ds[factor].values):
            sel = ds["outcome"].values[ds[factor].values == value]
            rows.append({"factor": factor, "value": value, "cases": len(sel),
                         **{o: int((sel == o).sum()) for o in OUTCOMES},
                         "convergence_rate": float((sel == "converged").mean())})
    return pd.DataFrame(rows)
