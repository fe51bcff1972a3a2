"""``docs/results.md``: a page generated from scene summaries, never typed by hand."""

from __future__ import annotations

import datetime
import os
import platform

import numpy as np
import pandas as pd

from breastcore.inverse.uncertainty import DETERMINED_FACTOR
from breastcore.io.datasets import open_dataset
from breastcore.model.mesh import LEVEL_NODE_COUNTS
from breastcore.model.parameters import IDENTIFIED
from breastcore.report import paper_values as paper
from breastcore.report.summaries import error_table, stability_table


def _machine():
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{platform.system()} {platform.machine()}, {cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def _markdown(table, floatfmt):
    """A markdown table with empty cells where a value is missing (the paper has no such row)."""
    return table.astype(object).where(table.notna(), None).to_markdown(index=False, missingval="",
                                                                        floatfmt=floatfmt)


def synthetic_section(name, ds):
    table = error_table(ds)
    truth_mesh = ds.attrs["truth_mesh"]         # set by every synthetic summary: no default level
    where = ("data solved on each level itself (same-mesh, an inverse crime: the paper's Table 1 layout)"
             if truth_mesh == "same" else
             f"data solved on the {truth_mesh} level, meshed by gmsh at the true R, H (cross-mesh)")
    lines = [
        f"### Scene `{name}`: parameter error (%) per method, mesh and initial offset", "",
        f"Mean |estimate/truth − 1| in %, {where}; "
        "`residual` is the RMS relative measurement residual, `time_s` the identification wall time; "
        "`consistent`, `misfit` and `not_converged` count the runs of each fit verdict (breastcore.inverse.verdict), "
        "not the optimiser's exit flags.", "",
        table.reset_index().to_markdown(index=False, floatfmt=".4g"), ""]
    if "covered" in ds:
        lines += ["**95 % intervals** (linearised, under the identification's noise model): per mesh, the "
                  "fraction of runs whose interval contains the truth (coverage; 0.95 is the nominal value when "
                  "the data carry that noise), and the fraction in which the parameter is determined (interval "
                  f"within a factor {DETERMINED_FACTOR:g}; an undetermined parameter's interval is not reported and "
                  "does not cover).",
                  "", _markdown(coverage_table(ds), ".3g"), ""]
    key = ds.attrs.get("paper_table", "none")
    if key in paper.PARAMETER_TABLES:
        comparison = paper_comparison_table(ds, key)
        lines += [f"**Beside {paper.PARAMETER_TABLES[key][0]}**: mean |estimate/truth − 1| (%) per mesh over all "
                  "of this scene's runs on it (every offset), mean iterations and mean time (s); the paper's row is "
                  "that of the mesh with the same node count (its times are on an Intel i5-2450M); meshes the "
                  "paper has and this scene does not run are listed with the paper's row only. Empty: no value.", "",
                  _markdown(comparison, ".4g"), ""]
    return "\n".join(lines)


def coverage_table(ds) -> pd.DataFrame:
    """Per mesh: runs, and per parameter the coverage of the truth by the 95 % interval and the
    fraction of runs in which the parameter is determined."""
    mesh = ds["mesh"].values.astype(str)
    rows = []
    for level in dict.fromkeys(mesh):
        pick = mesh == level
        row = {"mesh": level, "runs": int(pick.sum())}
        row.update({f"{p} covered": ds["covered"].values[pick, j].mean() for j, p in enumerate(IDENTIFIED)})
        row.update({f"{p} determined": ds["determined"].values[pick, j].mean() for j, p in enumerate(IDENTIFIED)})
        rows.append(row)
    return pd.DataFrame(rows)


def paper_comparison_table(ds, key) -> pd.DataFrame:
    """Our mean parameter error per mesh, each row followed by the paper's row for that mesh.

    ``key`` selects the paper's table (:data:`breastcore.report.paper_values.PARAMETER_TABLES`).
    Ours: the mean over the scene's runs on the mesh (every method and offset) of
    ``100 |estimate/truth − 1|``, the mean iterations and the mean wall time in s.
    The paper's: its row for the mesh of the same node count (NaN where it has none);
    iterations and time only where it gives them (the annex, case A). The paper's
    rows for meshes the scene did not run follow, alone, so that none is dropped.
    """
    reference = paper.PARAMETER_TABLES[key][1]
    extra = paper.ANNEX_A_CYCLES_TIME if key == "annex_a" else {}
    error = 100 * np.abs(ds["relative_error"].values)
    mesh = ds["mesh"].values.astype(str)
    rows = []

    def paper_row(level):
        theirs = np.array([reference[level][p] for p in IDENTIFIED]) if level in reference else np.full(6, np.nan)
        return {"mesh": level, "source": "paper", **dict(zip(IDENTIFIED, theirs)), "mean": theirs.mean(),
                "iterations": extra.get(level, {}).get("iterations", np.nan),
                "time_s": extra.get(level, {}).get("time_s", np.nan)}

    for level in dict.fromkeys(mesh):
        pick = mesh == level
        ours = error[pick].mean(axis=0)
        rows.append({"mesh": level, "source": f"ours ({int(pick.sum())} runs)", **dict(zip(IDENTIFIED, ours)),
                     "mean": ours.mean(), "iterations": ds["iterations"].values[pick].mean(),
                     "time_s": ds["wall_time"].values[pick].mean()})
        rows.append(paper_row(level))
    rows += [paper_row(level) for level in reference if level not in set(mesh)]
    return pd.DataFrame(rows)


def level_table(ds) -> pd.DataFrame:
    """The paper's Table 2 layout: per mesh level, the measurement residuals and the relative run time.

    Medians over the scene's runs of each level (every method and offset), rows from
    the coarsest level to the finest. The run time is relative to the scene's
    coarsest level (fewest nodes), as the paper's is to its coarse mesh.
    ``residual_at_truth`` is the paper's Table 2 quantity: the mean over the
    measurements of ``(M_level(Λ̄)/M_truth − 1)²``, the level's measurements at the
    true parameters against the truth mesh's (present when the summary carries
    ``discretisation_error``). The paper's values are beside, where it has the level.
    """
    df = pd.DataFrame({"mesh": ds["mesh"].values.astype(str), "residual": ds["measurement_residual"].values,
                       "time_s": ds["wall_time"].values, "iterations": ds["iterations"].values})
    table = df.groupby("mesh", sort=False).median()
    table.insert(0, "runs", df.groupby("mesh", sort=False).size())
    table = table.loc[sorted(table.index, key=lambda m: LEVEL_NODE_COUNTS.get(m, np.inf))]
    table["relative_time"] = table["time_s"] / table["time_s"].iloc[0]
    if "discretisation_error" in ds:
        gap = ds["discretisation_error"]
        mse = (gap ** 2).mean(dim=("posture", "quantity"))
        table["residual_at_truth"] = [float(mse.sel(level=m)) if m in gap["level"].values else np.nan
                                      for m in table.index]
    table["paper_residual_at_truth"] = [paper.TABLE2.get(m, {}).get("residual", np.nan) for m in table.index]
    table["paper_relative_time"] = [paper.TABLE2.get(m, {}).get("relative_time", np.nan) for m in table.index]
    return table


def measurement_table(ds, with_paper=False) -> pd.DataFrame:
    """The paper's annex layout: mean ``100 |M(Λ̂)/M̄ − 1|`` per measurement m1..m15 at the estimate.

    One row per mesh (mean over its runs); with ``with_paper``, then the paper's
    annex rows (case A), under its own labels Coarse, Medium and Thin, for which it
    gives no node counts. ``avg`` is the mean over the 15 and ``cost`` our mean final
    cost E; the paper's printed cost (1.99e-6 on Coarse) is left out, since it cannot
    be the relative cost of its own errors (its m5, m10 and m15 alone give ≥ 0.017).
    """
    error = 100 * np.abs(ds["final_measurement_error"].values)            # (run, posture, quantity)
    error = error.reshape(error.shape[0], -1)
    mesh = ds["mesh"].values.astype(str)
    columns = [f"m{i + 1}" for i in range(error.shape[1])]
    rows = []
    for level in dict.fromkeys(mesh):
        pick = mesh == level
        ours = error[pick].mean(axis=0)
        rows.append({"mesh": f"{level} (ours)", **dict(zip(columns, ours)), "avg": ours.mean(),
                     "cost": ds["cost"].values[pick].mean()})
    if with_paper and error.shape[1] == 15:
        for label, values in paper.ANNEX_A_MEASUREMENTS.items():
            rows.append({"mesh": f"{label} (paper)", **dict(zip(columns, values)), "avg": np.mean(values),
                         "cost": np.nan})
    return pd.DataFrame(rows)


def evolution_table(ds, first=15, last=25) -> pd.DataFrame:
    """Mean of ``100 |Λ/Λ̄ − 1|`` and standard deviation of ``100 (Λ/Λ̄ − 1)`` over iterations ``first``–``last``.

    One row per run, from the summary's ``relative_error_history`` (the summary is the
    rule's only input). Runs that stopped before ``first`` use their last
    ``last − first + 1`` iterations (the column ``iterations`` says which). The
    differences are unsigned, as the paper prints them. After each mesh's first run,
    the paper's Tables 3 and 4 for that mesh, where it has them.
    """
    rows, shown = [], set()
    history = ds["relative_error_history"].values
    for run, (mesh, method) in enumerate(zip(ds["mesh"].values.astype(str), ds["method"].values)):
        values = 100 * history[run]
        values = values[np.all(np.isfinite(values), axis=1)]
        n = values.shape[0]
        lo, hi = (first, min(last, n - 1)) if n - 1 >= first else (max(0, n - 1 - (last - first)), n - 1)
        window = values[lo:hi + 1]
        row = {"source": f"ours, {method}", "mesh": mesh, "iterations": f"{lo}–{hi}"}
        for j, name in enumerate(IDENTIFIED):
            row[f"{name} mean %"] = np.abs(window[:, j]).mean()
            row[f"{name} sd %"] = window[:, j].std(ddof=1) if len(window) > 1 else np.nan
        rows.append(row)
        if mesh in paper.EVOLUTION_MEAN and mesh not in shown:
            shown.add(mesh)
            row = {"source": "paper", "mesh": mesh, "iterations": f"{first}–{last}"}
            for name in IDENTIFIED:
                row[f"{name} mean %"] = paper.EVOLUTION_MEAN[mesh][name]
                row[f"{name} sd %"] = paper.EVOLUTION_SD[mesh][name]
            rows.append(row)
    return pd.DataFrame(rows)


def _offsets(ds):
    return ", ".join(f"{o:.0%}" for o in sorted(set(ds["offset"].values.tolist())))


def levels_section(name, ds):
    table = level_table(ds)
    return "\n".join([
        f"### Scene `{name}`: measurement residual and run time per mesh level (the paper's Table 2 layout)", "",
        "Per level: `residual`, the median RMS relative measurement residual sqrt(E/n) at the estimate against the "
        "truth data; `residual_at_truth`, the paper's Table 2 quantity, the mean squared relative difference of the "
        "level's 15 measurements at the true Λ̄ from the truth mesh's (the discretisation gap); the median "
        "identification time, and that time relative to the scene's coarsest level. The paper's values are in the "
        "`paper_` columns, empty where it has no such level.", "",
        _markdown(table.reset_index(), ".4g"), ""])


def measurements_section(name, ds):
    with_paper = ds.attrs.get("paper_table") == "annex_a"
    table = measurement_table(ds, with_paper)
    text = ("Mean |M(Λ̂)/M̄ − 1| in % per measurement (m1–m5 standing, m6–m10 bent 45°, m11–m15 on all fours, "
            "each as volume, area, height, frontal depth, back depth; M̄ are the scene's data, with noise where it "
            "adds noise) and our mean final cost E.")
    if with_paper:
        text += (" Then the paper's annex rows (case A). It labels them Coarse, Medium and Thin without node "
                 "counts, while its annex names its three meshes coarse, thin and ultra-thin (N = 226, 1014, "
                 "2498), so its Medium and Thin are probably N = 1014 and 2498. Its measurement order is read as "
                 "ours: its large e5, e10 and e15 match our back depths. Its printed costs (1.99e-6 on Coarse) "
                 "cannot be the relative cost of its own errors (e5, e10 and e15 alone give ≥ 0.017), so they "
                 "are left out.")
    return "\n".join([f"### Scene `{name}`: measurement error (%) at the estimate (the paper's annex layout)", "",
                      text, "", _markdown(table, ".3g"), ""])


def evolution_section(name, ds):
    table = evolution_table(ds)
    return "\n".join([
        f"### Scene `{name}`: parameters over iterations 15–25 (mean and standard deviation of the difference "
        "from Λ̄, %)", "",
        "The figure is `results/scenes/" + name + "/convergence.png` (parameter error and cost per iteration). "
        "Means are of |Λ/Λ̄ − 1|, which is how the paper's Tables 3 and 4 print them (with no sign). Our runs "
        f"start {_offsets(ds)} off; the paper's guesses are \"up to 60 %\" off (config/paper.yaml says why).", "",
        _markdown(table, ".4g"), ""])


def sensitivity_tables(ds) -> dict:
    """``{title: DataFrame}``: one row per measurement m1..m15, one column per parameter.

    Ours (finite ±δ and linearised, signed), their difference, and the paper's table
    (magnitudes), from a synthetic summary with ``sensitivity_*`` variables.
    """
    labels = [f"m{i + 1} {m}" for i, m in enumerate(ds["measurement"].values)]
    tables = {}
    delta = float(ds.attrs.get("sensitivity_delta", 0.1))
    for key, title in (("finite", f"finite ±{delta:.0%} (ours)"), ("linearised", "linearised (ours)"),
                       ("difference", "finite − linearised (ours)")):
        if f"sensitivity_{key}" in ds:
            tables[title] = pd.DataFrame(ds[f"sensitivity_{key}"].values.T, index=labels, columns=IDENTIFIED)
    if len(labels) == paper.SENSITIVITY.shape[0]:
        tables["paper (magnitudes, its very-thin mesh)"] = pd.DataFrame(paper.SENSITIVITY, index=labels,
                                                                        columns=IDENTIFIED)
    return tables


def _weakest(table, count=5):
    """The ``count`` measurements with the smallest row norm (least influence on Λ); NaN rows excluded."""
    norms = np.sqrt(np.sum(table.values ** 2, axis=1))
    norms[~np.isfinite(norms)] = np.inf
    return ", ".join(table.index[i].split()[0] for i in sorted(np.argsort(norms)[:count]))


def sensitivity_section(name, ds):
    a = ds.attrs
    lines = [f"### Scene `{name}`: sensitivity of Λ to each measurement (6×15, shown transposed)", "",
             f"Relative sensitivities (m_i/Λ_j) ∂Λ_j/∂m_i at the estimate of the scene's first run, on the "
             f"{a.get('sensitivity_mesh', '?')} mesh. Ours: m1–m5 are standing, m6–m10 bent 45°, m11–m15 on "
             "all fours, each in the order volume, area, height, frontal depth, back depth; the paper names "
             "the five measures and the three postures but does not number m1–m15, so its rows are matched to "
             "ours by number, read in the same order. Ours are signed; the "
             "paper prints magnitudes.",
             f"Linearised (JᵀWJ)⁻¹JᵀW: rank {a.get('sensitivity_linearised_rank', '?')}, condition number "
             f"{float(a.get('sensitivity_linearised_condition', np.nan)):.3g}."]
    if "sensitivity_finite_rank" in a:
        lines.append(f"Finite ±{float(a.get('sensitivity_delta', 0.1)):.0%}: rank {a['sensitivity_finite_rank']}, "
                     f"condition number {float(a['sensitivity_finite_condition']):.3g}, "
                     f"{a.get('sensitivity_finite_failures', 0)} measurement(s) whose re-identification failed, "
                     f"{a.get('sensitivity_finite_iteration_limited', 0)} of the re-identifications stopped at their "
                     "iteration limit (their estimate after that many iterations is used, as in the paper).")
    lines.append("")
    tables = sensitivity_tables(ds)
    for title, table in tables.items():
        lines += [f"**{title}** (five weakest measurements: {_weakest(table)})", "",
                  table.reset_index(names="measurement").to_markdown(index=False, floatfmt=".4g"), ""]
    return "\n".join(lines)


def stability_section(name, ds):
    counts = {o: int((ds["outcome"].values == o).sum()) for o in ("converged", "unverified", "nan", "solve_error",
                                                                   "crash")}
    total = ds.sizes["case"]
    table = stability_table(ds)
    table["value"] = [f"{v:g}" if isinstance(v, float) else str(v) for v in table["value"]]
    return "\n".join([
        f"### Scene `{name}`: stability on stiff and extreme cases", "",
        f"{total} cases; outcomes: " + ", ".join(f"{k} {v}" for k, v in counts.items()) +
        f"; convergence rate {counts['converged'] / max(total, 1):.1%}.", "",
        table.to_markdown(index=False, floatfmt=".3g"), "", *guesses_part(ds)])


def guesses_part(ds):
    """Lines of the stability section about the identifications from extreme guesses."""
    if "guess" not in ds.dims:
        return []
    table = pd.DataFrame({"mesh": ds["guess_mesh"].values, "guess": ds["guess_label"].values,
                          "outcome": ds["guess_outcome"].values, "iterations": ds["guess_iterations"].values,
                          "max error": ds["guess_max_error"].values, "final E": ds["guess_cost"].values,
                          "time s": ds["guess_wall_time"].values})
    recovered = int((table["outcome"] == "recovered").sum())
    return ["Identification from extreme guesses (moduli ×0.25 and ×4, inverse-crime data at Λ̄; LM with the "
            f"implicit Jacobian): {recovered} of {len(table)} recovered every parameter to 1e-4.", "",
            table.to_markdown(index=False, floatfmt=".3g"), ""]


def render(summaries, commands):
    """Markdown of the page from ``{scene: summary path}``."""
    parts = ["# Results", "",
             "Generated by the `results_page` rule from the scene summaries of one workflow run; do not edit.", "",
             f"- Machine: {_machine()}",
             f"- Date: {datetime.date.today().isoformat()}",
             "- Commands: " + "; ".join(f"`{c}`" for c in commands), "",
             "Where our numbers differ from the paper's: ρ, c, t_s, δ and the measurement formulas are the "
             "spec's defaults, not the paper's (which does not give them); c comes from the calibration scene "
             "(docs/results-calibration.md). Below the slip threshold ρ g V/|Γ_B| (311 Pa at the paper's Λ̄; "
             "c = 100 Pa, the first guess, is below it) the standing breast slides down the back and crushes "
             "against the fold, its shape is not mesh-converged at these mesh sizes, and identification across "
             "meshes (truth on a finer mesh) carries a large discretisation gap.", ""]
    for name, path in summaries.items():
        ds = open_dataset(path)
        kind = ds.attrs.get("scene_kind")
        if kind == "synthetic":
            parts.append(synthetic_section(name, ds))
            tables = ds.attrs.get("tables", "").split(",")
            if "levels" in tables:
                parts.append(levels_section(name, ds))
            if "measurements" in tables:
                parts.append(measurements_section(name, ds))
            if "evolution" in tables:
                parts.append(evolution_section(name, ds))
            if "sensitivity_linearised" in ds:
                parts.append(sensitivity_section(name, ds))
        elif kind == "stability":
            parts.append(stability_section(name, ds))
        elif kind == "calibration":
            from breastcore.report.calibration_page import calibration_section
            parts.append(calibration_section(name, ds))
    return "\n".join(parts)
