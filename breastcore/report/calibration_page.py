"""The calibration scene on the results page: its tables, figure and section (issue #18)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from breastcore.model.mesh import LEVEL_NODE_COUNTS
from breastcore.pipeline.calibration_plan import FIGURE
from breastcore.studies.chassaignac_rule import CRITERIA


def residual_figure(summary, path):
    """The Table-2 residual against level, one line per c, the paper's beside (log scale)."""
    from matplotlib import colormaps

    from breastcore.report.plots import _save, subplots

    levels = [str(v) for v in summary["table2_level"].values]
    x = np.arange(len(levels))
    fig, ax = subplots(figsize=(7, 4.5))
    for i, c in enumerate(summary["chassaignac"].values):
        y = summary["table2_residual"].values[i]
        ax.semilogy(x, np.where(y > 0, y, np.nan), "o-", color=colormaps["viridis"](i / max(len(summary["chassaignac"]) - 1,
                                                                                      1)), label=f"c = {c:g} Pa")
    theirs = summary["paper_table2_residual"].values
    ax.semilogy(x, theirs, "ks--", label="paper (its c not given)")
    ax.set_xticks(x, [f"{lv}\n({LEVEL_NODE_COUNTS.get(lv, '?')})" for lv in levels], fontsize=8)
    ax.set_ylabel(f"mean (M/M_{summary.attrs.get('reference', 'reference')} − 1)² at the truth")
    ax.set_xlabel("mesh level (the paper's node count)")
    chosen = float(summary.attrs.get("chosen_chassaignac", np.nan))
    ax.set_title("Table-2 residual per level" + (f"; chosen c = {chosen:g} Pa" if np.isfinite(chosen) else
                                                  "; no c of the grid satisfies the rule"))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    _save(fig, path)


def _markdown(table, floatfmt=".3g"):
    return table.astype(object).where(table.notna(), None).to_markdown(index=False, missingval="", floatfmt=floatfmt)


def _worst(values, labels, lowest):
    """``"value (where)"`` of the smallest (``lowest``) or largest finite value; a NaN anywhere is named first."""
    values = np.asarray(values, float)
    if values.size == 0:
        return ""
    if not np.all(np.isfinite(values)):
        return f"NaN ({labels[int(np.flatnonzero(~np.isfinite(values))[0])]})"
    i = int(np.argmin(values) if lowest else np.argmax(values))
    return f"{values[i]:.3g} ({labels[i]})"


def calibration_table(ds) -> pd.DataFrame:
    """One row per c: margins, the worst check of each criterion and where, the Jacobian, identification errors."""
    admissible = ds["admissible"].values.astype(bool)
    labels = [str(v) for v in ds["point"].values]
    levels = [str(v) for v in ds["level"].values]
    pairs = [f"{lv}, {labels[p]}" for lv in levels for p in range(len(labels)) if admissible[p]]
    corners = [p for p in range(len(labels)) if admissible[p]]
    rows = []
    for i, c in enumerate(ds["chassaignac"].values):
        margin = ds["sliding_margin"].values[i]
        standing = ds["standing_min_det_F"].values[i][:, admissible].reshape(-1)
        behind = 1e3 * ds["torso_penetration"].values[i][:, admissible].max(axis=-1).reshape(-1) \
            if "torso_penetration" in ds else np.full(len(pairs), np.nan)
        depth = _worst(behind, pairs, lowest=False) if np.isfinite(behind).any() else "not recorded"
        singular = ds["singular_value"].values[i]
        row = {"c (Pa)": f"{c:g}", "margin at truth": margin[0],
               "min margin": np.nanmin(margin[admissible]),
               "min standing det F (level, point)": _worst(standing, pairs, lowest=True),
               "max depth behind torso plane, mm (level, point)": depth,
               "max difference (point)": _worst(ds["measurement_difference"].values[i][corners],
                                                [labels[p] for p in corners], lowest=False),
               "max sliding difference (point)": _worst(ds["sliding_difference"].values[i][corners],
                                                        [labels[p] for p in corners], lowest=False),
               "max nonlinearity (parameter)": _worst(ds["nonlinearity"].values[i],
                                                      [str(v) for v in ds["parameter"].values], lowest=False),
               "σ_min": singular[-1], "σ_max/σ_min": singular[0] / singular[-1]}
        if "identification_error" in ds:
            for k, mesh in enumerate(ds["identify_mesh"].values):
                row[f"id. error % {mesh}"] = 100 * np.nanmean(ds["identification_error"].values[i, k])
        for k, criterion in enumerate(ds["criterion"].values):
            row[CRITERIA[str(criterion)][0]] = "pass" if ds["criterion_passed"].values[i, k] else "fail"
        rows.append(row)
    return pd.DataFrame(rows)


def residual_table(ds) -> pd.DataFrame:
    """The Table-2 residual: one row per level, one column per c, the paper's last."""
    table = pd.DataFrame({"level": [str(v) for v in ds["table2_level"].values],
                          "nodes (paper)": [LEVEL_NODE_COUNTS.get(str(v), np.nan) for v in ds["table2_level"].values]})
    for i, c in enumerate(ds["chassaignac"].values):
        table[f"c = {c:g} Pa"] = ds["table2_residual"].values[i]
    table["paper"] = ds["paper_table2_residual"].values
    return table


def calibration_section(name, ds) -> str:
    """The results-page section of a calibration scene summary."""
    a = ds.attrs
    chosen = float(a.get("chosen_chassaignac", np.nan))
    left_out = int((ds["admissible"].values == 0).sum())
    corners = ds.sizes["point"] - 1
    lines = [f"### Scene `{name}`: calibration of the Chassaignac coefficient c", "",
             f"**Rule**: {a['rule']}.", "",
             (f"**Chosen: c = {chosen:g} Pa.**" if np.isfinite(chosen) else
              "**No c of the grid satisfies the rule**: no default is chosen from this study."), ""]
    if left_out:
        lines += [f"{left_out} of the {corners} box corners have H ≥ R, which is no cap (and which identification, "
                  "working in logit(H/R), never reaches): they are left out of the rule.", ""]
    lines += [f"Table-2 residual, mean over the measurements of (M_level/M_{a['reference']} − 1)² at the truth, per c "
              f"(figure: `results/scenes/{name}/{FIGURE}`); the paper's beside (it gives no c):", "",
              _markdown(residual_table(ds)), "",
              f"Per c: the sliding margin c/(ρ g V/|Γ_B|) at the truth and its minimum over the admissible corners; "
              f"the worst check of each criterion and where ((a) min det F in {a['det_F_posture']} over every level "
              f"and point; the deepest node behind the torso plane y = 0 over every level, point and posture (not a "
              f"criterion: the model has no chest-wall contact); (b) max |M_{a['compare_level']}/M_{a['reference']} − 1| "
              f"over the points, and the part of it "
              f"that the back's sliding adds (criterion (b): the same minus its value at the grid's largest c); (c) the "
              f"nonlinearity of the probe on {a['probe_level']}); the singular values of the relative Jacobian on "
              f"{a['jacobian_level']}; the mean parameter error (%) of the cross-mesh identifications "
              f"({float(a.get('identification_offset', np.nan)):.0%} off, truth on the reference level meshed by "
              "gmsh at the true R, H); and each criterion's verdict.", "",
              _markdown(calibration_table(ds)), ""]
    failures = [(c, text) for c, text in zip(ds["chassaignac"].values, ds["failures"].values) if str(text)]
    if failures:
        lines += ["What fails, per c:", ""] + [f"- c = {c:g} Pa: {text}" for c, text in failures] + [""]
    return "\n".join(lines)
