"""The calibration scene of the Chassaignac coefficient c (issue #18): its jobs, summary, figure and page section.

For each c of a grid, at the truth Λ̄ (the paper's by default) and at the corners of
a box around it, the scene measures what the choice of c does to the model:

- the paper's Table-2 residual per level at Λ̄, ``mean_i (M_i(level)/M_i(reference) − 1)²``;
- the sliding margin ``c / (ρ g V/|Γ_B|)`` (:mod:`breastcore.model.sliding`);
- the standing min det F on every level up to the reference, and the largest relative
  difference of the measurements between a fine level and the reference;
- the uniqueness probe at Λ̄ (:func:`breastcore.studies.calibration.nonlinearity`);
- the singular values of the relative Jacobian at Λ̄ on one level;
- cross-mesh identifications (truth on the reference level meshed by gmsh at the
  true R, H), through the plan's ordinary mesh, solve, measure and identify jobs.

Then :func:`breastcore.studies.chassaignac_rule.choose_chassaignac` picks the default c. The
jobs are planned by :mod:`breastcore.pipeline.calibration_plan` and computed by
:mod:`breastcore.studies.calibration`; this module reads them back into the scene summary and
the report.
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pandas as pd
import xarray as xr

from breastcore.io.datasets import PARAMETER_UNIT_LIST, _var, open_dataset, provenance
from breastcore.model.parameters import IDENTIFIED, ParameterError, Parameters
from breastcore.model.sliding import slip_threshold
from breastcore.pipeline.calibration_plan import SHORT
from breastcore.report import paper_values as paper
from breastcore.studies.chassaignac_rule import CRITERIA, choose_chassaignac


# -- summary --------------------------------------------------------------------------
def calibration_summary(spec, name, config_hash=None) -> xr.Dataset:
    """The scene summary: every quantity of the study per c, the rule's verdict and the chosen c.

    Parameters
    ----------
    spec : dict
        The scene spec of :func:`plan_calibration`.
    name : str
    config_hash : str, optional

    Returns
    -------
    xarray.Dataset
        Dimensions ``chassaignac`` (c, Pa), ``level`` (the levels, then the
        reference), ``point`` (truth, then the box corners), ``posture``,
        ``quantity``, ``parameter``, ``criterion``; the chosen c in the attribute
        ``chosen_chassaignac`` (NaN when no c of the grid satisfies the rule) and
        the sentence ``choice``.

    Notes
    -----
    With ``M(ℓ, p)`` the 15 measurements of level ``ℓ`` at point ``p`` and ``r`` the
    reference level:

    - ``table2_residual(c, ℓ) = mean_i (M_i(ℓ, Λ̄)/M_i(r, Λ̄) − 1)²``, the paper's Table 2;
    - ``measurement_difference(c, p) = max_i |M_i(compare, p)/M_i(r, p) − 1|``;
    - ``sliding_difference(c, p) = measurement_difference(c, p) − measurement_difference(c_max, p)``,
      ``c_max`` the grid's largest c: the part of the level gap that the back's sliding adds
      to the meshes' own discretisation error (which ``measurement_difference(c_max, p)`` is);
    - ``sliding_margin(c, p) = c / (ρ g V(p)/|Γ_B(p)|)``;
    - ``identification_error(c, mesh, start) = mean_j |Λ̂_j/Λ̄_j − 1|``, with the identification's
      fit verdict, ``identification_verdict`` (``identification_success`` is the optimiser's exit only).

    A value from a solve that did not converge is NaN, and fails the rule.
    """
    study = _study(spec)
    data = {**_solve_variables(study, spec), **_study_variables(study, spec)}
    data.update(_identification_variables(spec))
    ds = xr.Dataset(data, coords=_coordinates(study, spec))
    ds.attrs = _summary_attrs(study, spec, name, config_hash)
    return ds


def _study(spec):
    """The arrays of the study, read from the level-point and uniqueness datasets, and the rule's choice."""
    cases = spec["cases"]
    levels = [*spec["levels"], spec["reference"]]
    c_values = np.array([case["chassaignac"] for case in cases], float)
    per_level = [[open_dataset(case["levels"][level]) for level in levels] for case in cases]
    first = per_level[0][0]
    labels = [str(v) for v in first["point"].values]
    postures = [str(v) for v in first["posture"].values]

    def stack(variable, missing=None):
        """(c, level, point, posture...) of ``variable``; ``missing`` fills a dataset that lacks it, if given."""
        return np.array([[ds[variable].values if missing is None or variable in ds else
                          np.full(ds["converged"].shape, missing) for ds in row] for row in per_level])

    measurement = stack("measurement")
    converged = stack("converged").astype(bool)
    min_det = np.where(converged, stack("min_det_F"), np.nan)
    # NaN from any level dataset written before the depth was recorded
    penetration = np.where(converged, stack("torso_penetration", missing=np.nan), np.nan)
    ratio = measurement[:, :-1] / measurement[:, -1:] - 1.0                  # (c, level, point, posture, quantity)
    residual = np.mean(ratio[:, :, 0] ** 2, axis=(2, 3))                    # at the truth, point 0
    compare = spec["levels"].index(spec["compare_level"])
    difference = np.max(np.abs(ratio[:, compare]), axis=(2, 3))              # (c, point)
    sliding = difference - difference[np.argmax(c_values)][None, :]           # beyond the stiffest back's gap
    standing = min_det[..., postures.index(spec["det_F_posture"])]           # (c, level, point)

    points = [_parameters(spec["constants"], p["parameters"]) for p in spec["points"]]
    admissible = np.array([p is not None for p in points])
    threshold = np.array([slip_threshold(p) if p is not None else np.nan for p in points])
    probes = [open_dataset(case["uniqueness"]) for case in cases]
    jacobian = [row[levels.index(spec["jacobian_level"])] for row in per_level]

    table = criteria_table(c_values, levels, labels, admissible, standing, sliding,
                           np.array([ds["nonlinearity"].values for ds in probes]), spec)
    choice = choose_chassaignac(table, **spec["criteria"])
    return SimpleNamespace(levels=levels, c_values=c_values, first=first, labels=labels, postures=postures,
                           stack=stack, measurement=measurement, converged=converged, min_det=min_det,
                           penetration=penetration,
                           residual=residual, difference=difference, sliding=sliding, standing=standing,
                           admissible=admissible, threshold=threshold, probes=probes, jacobian=jacobian,
                           choice=choice, criteria=list(CRITERIA))


def _solve_variables(s, spec):
    """The cold solves' variables, per c, level, point and posture."""
    return {
        "measurement": _var(("chassaignac", "level", "point", "posture", "quantity"), s.measurement,
                            str(s.first["measurement"].attrs["units"]),
                            "cold-solve measurements (NaN unless converged); units per quantity in quantity_units"),
        "converged": _var(("chassaignac", "level", "point", "posture"), s.converged.astype(np.int8), "1",
                          "1 where the cold solve converged"),
        "outcome": _var(("chassaignac", "level", "point", "posture"), s.stack("outcome").astype(str), "1",
                        "how the cold solve ended (converged, solve_error, inadmissible, crash)"),
        "message": _var(("chassaignac", "level", "point", "posture"), s.stack("message").astype(str), "1",
                        "failure diagnostics of the cold solve (empty when converged)"),
        "min_det_F": _var(("chassaignac", "level", "point", "posture"), s.min_det, "1",
                          "smallest det F of the converged cold solve (NaN unless converged)"),
        "torso_penetration": _var(("chassaignac", "level", "point", "posture"), s.penetration, "m",
                                  "largest depth of a node behind the torso plane y = 0 in the converged cold "
                                  "solve (NaN unless converged, or not recorded)"),
        "iterations": _var(("chassaignac", "level", "point", "posture"), s.stack("iterations"), "1",
                           "minimiser iterations of the cold solve"),
        "wall_time": _var(("chassaignac", "level", "point", "posture"), s.stack("wall_time"), "s",
                          "wall time of the cold solve"),
    }


def _study_variables(s, spec):
    """The per-point, per-level and per-c results of the study, and the rule's verdict per c."""
    return {
        "point_parameters": _var(("point", "parameter"), s.first["point_parameters"].values, PARAMETER_UNIT_LIST,
                                 "Λ of the point; units per parameter in parameter_units"),
        "admissible": _var(("point",), s.admissible.astype(np.int8), "1",
                           "1 where the point is a cap (0 < H < R); 0: left out, not solved"),
        "slip_threshold": _var(("point",), s.threshold, "Pa",
                               "ρ g V/|Γ_B| of the gravity-free cap at the point (NaN if inadmissible)"),
        "sliding_margin": _var(("chassaignac", "point"), s.c_values[:, None] / s.threshold[None, :], "1",
                               "c / (ρ g V/|Γ_B|): above 1 the back holds the standing breast by friction alone"),
        "table2_residual": _var(("chassaignac", "table2_level"), s.residual, "1",
                                f"mean over the measurements of (M_level/M_{spec['reference']} − 1)² at the truth "
                                "(the paper's Table 2)"),
        "paper_table2_residual": _var(("table2_level",),
                                      np.array([paper.TABLE2.get(lv, {}).get("residual", np.nan)
                                                for lv in spec["levels"]]), "1",
                                      "the paper's Table 2 residual of the level of the same node count (NaN: none)"),
        "standing_min_det_F": _var(("chassaignac", "level", "point"), s.standing, "1",
                                   f"min det F in posture {spec['det_F_posture']} (NaN unless converged)"),
        "measurement_difference": _var(("chassaignac", "point"), s.difference, "1",
                                       f"max over the measurements of |M_{spec['compare_level']}/"
                                       f"M_{spec['reference']} − 1| (NaN unless all converged)"),
        "sliding_difference": _var(("chassaignac", "point"), s.sliding, "1",
                                   f"measurement_difference minus its value at the same point for the grid's largest c "
                                   f"({s.c_values.max():g} Pa): what the back's sliding adds to the meshes' own gap"),
        "nonlinearity": _var(("chassaignac", "parameter"), np.array([ds["nonlinearity"].values for ds in s.probes]),
                             "1", f"uniqueness probe on {spec['probe_level']} at the truth: max_i |(M_i(+) − M_i(0)) − "
                                  "(M_i(0) − M_i(−))| / |M_i(0)|"),
        "first_difference": _var(("chassaignac", "parameter"),
                                 np.array([ds["first_difference"].values for ds in s.probes]), "1",
                                 "uniqueness probe: max_i |M_i(+) − M_i(−)| / (2 |M_i(0)|)"),
        "singular_value": _var(("chassaignac", "singular"), np.array([ds["singular_value"].values for ds in s.jacobian]),
                               "1", f"singular values of the relative Jacobian ∂ln M/∂ln Λ at the truth on "
                                    f"{spec['jacobian_level']}"),
        "relative_jacobian": _var(("chassaignac", "posture", "quantity", "parameter"),
                                  np.array([ds["relative_jacobian"].values for ds in s.jacobian]), "1",
                                  f"relative Jacobian ∂ln M/∂ln Λ at the truth on {spec['jacobian_level']}"),
        "criterion_passed": _var(("chassaignac", "criterion"),
                                 np.array([[int(s.choice.passed[c][k]) for k in s.criteria] for c in s.c_values], np.int8),
                                 "1", "1 where every check of the criterion passes"),
        "passed": _var(("chassaignac",), np.array([int(all(s.choice.passed[c].values())) for c in s.c_values], np.int8),
                       "1", "1 where the c satisfies the rule (all three criteria)"),
        "failures": _var(("chassaignac",), np.array(["; ".join(s.choice.failures[c]) for c in s.c_values]), "1",
                         "the criteria that fail, with the worst check and where"),
    }


def _coordinates(s, spec):
    """The dimensions' coordinates, with units and meanings."""
    return {
        "chassaignac": _var(("chassaignac",), s.c_values, "Pa", "Chassaignac coefficient c"),
        "level": _var(("level",), np.array(s.levels), "1", "mesh level (the last is the reference)"),
        "table2_level": _var(("table2_level",), np.array(spec["levels"]), "1",
                             "mesh level compared with the reference"),
        "point": _var(("point",), np.array(s.labels), "1", "point label (truth or box corner)"),
        "posture": s.first["posture"].variable, "quantity": s.first["quantity"].variable,
        "quantity_units": s.first["quantity_units"].variable, "parameter": s.first["parameter"].variable,
        "parameter_units": s.first["parameter_units"].variable,
        "criterion": _var(("criterion",), np.array(s.criteria), "1",
                          "criterion of the rule: " + ", ".join(f"{CRITERIA[k][0]} {k}" for k in s.criteria)),
    }


def _summary_attrs(s, spec, name, config_hash):
    """Provenance, the chosen c and the rule, as the summary's attributes."""
    truth_parameters = {**spec["constants"], **spec["truth"]}
    chosen = np.nan if s.choice.chassaignac is None else s.choice.chassaignac
    return provenance("scene", truth_parameters, config_hash, scene=name, scene_kind="calibration",
                          title=f"calibration of the Chassaignac coefficient, scene {name}",
                          chosen_chassaignac=chosen, choice=s.choice.describe(), rule=rule_text(spec),
                          reference=spec["reference"], compare_level=spec["compare_level"],
                          probe_level=spec["probe_level"], jacobian_level=spec["jacobian_level"],
                          det_F_posture=spec["det_F_posture"], probe_epsilon=float(spec["epsilon"]),
                          min_det_F=float(spec["criteria"]["min_det_F"]),
                          max_sliding_difference=float(spec["criteria"]["max_sliding_difference"]),
                          linear_threshold=float(spec["criteria"]["linear_threshold"]),
                          box=json.dumps({"parameters": spec["box_parameters"], "factors": spec["box_factors"]}),
                          identification_offset=float(spec["offset"]))


def _parameters(constants, point):
    """The point's Parameters, or None if they are inadmissible (H ≥ R: no cap)."""
    try:
        return Parameters(**{**constants, **point})
    except ParameterError:
        return None


def _identification_variables(spec) -> dict:
    """``(chassaignac, identify_mesh, start)`` results of the cross-mesh identifications (none: no variables)."""
    meshes, starts = spec["identify_meshes"], int(spec["starts"])
    if not meshes:
        return {}
    shape = (len(spec["cases"]), len(meshes), starts)
    error, success, iterations, wall, cost = (np.full(shape, np.nan) for _ in range(5))
    paths, verdicts = np.full(shape, "", dtype=object), np.full(shape, "", dtype=object)
    for i, case in enumerate(spec["cases"]):
        for run in case["runs"]:
            index = (i, meshes.index(run["mesh"]), run["start"])
            ds = open_dataset(run["identification"])
            error[index] = float(np.mean(np.abs(ds["relative_error"].values)))
            success[index] = int(ds.attrs["success"])
            verdicts[index] = ds.attrs["verdict"]
            iterations[index] = int(ds.attrs.get("iterations", ds.sizes["iteration"] - 1))
            wall[index] = float(ds["wall_time"].values[-1])
            cost[index] = float(ds["cost"].values[-1])
            paths[index] = run["identification"]
    dims = ("chassaignac", "identify_mesh", "start")
    return {
        "identify_mesh": _var(("identify_mesh",), np.array(meshes), "1", "mesh level identified on"),
        "start": _var(("start",), np.arange(starts), "1", "initial guess (random, within ±offset of the truth)"),
        "identification_error": _var(dims, error, "1", "mean over the six parameters of |estimate/truth − 1|"),
        "identification_success": _var(dims, success, "1", "1 if the optimiser met its stopping test (what the "
                                       "estimate is worth: identification_verdict)"),
        "identification_verdict": _var(dims, verdicts.astype(str), "1", "fit verdict of the identification: "
                                       "consistent, misfit or not_converged (breastcore.inverse.verdict)"),
        "identification_iterations": _var(dims, iterations, "1", "accepted iterations of the identification"),
        "identification_wall_time": _var(dims, wall, "s", "identification wall time"),
        "identification_cost": _var(dims, cost, "1", "final cost E"),
        "identification": _var(dims, paths.astype(str), "1", "identification dataset"),
    }


def criteria_table(c_values, levels, labels, admissible, standing, difference, nonlinearity, spec) -> pd.DataFrame:
    """The rule's table of checks (:func:`~breastcore.studies.chassaignac_rule.choose_chassaignac`) from the study's arrays.

    Parameters
    ----------
    c_values : (n_c,) array
    levels : list of str
        Every level, the reference last.
    labels : list of str
        The points; only the ``admissible`` ones are checked.
    admissible : (n_point,) bool array
    standing : (n_c, n_level, n_point) array
        Standing min det F (NaN unless converged).
    difference : (n_c, n_point) array
        The sliding difference: the largest relative difference of the measurements
        between the compare level and the reference, minus its value for the grid's
        largest c at the same point.
    nonlinearity : (n_c, 6) array
        Uniqueness probe per parameter.
    spec : dict
        The scene spec (names of the posture, compare and probe levels).
    """
    rows = []
    for i, c in enumerate(c_values):
        for p, label in enumerate(labels):
            if not admissible[p]:
                continue
            for k, level in enumerate(levels):
                rows.append((c, "min_det_F", f"{spec['det_F_posture']} on {level} at {label}", standing[i, k, p]))
            rows.append((c, "sliding_difference", f"{spec['compare_level']} against {spec['reference']} at "
                                                  f"{label}", difference[i, p]))
        for j, name in enumerate(IDENTIFIED):
            rows.append((c, "nonlinearity", f"{name} on {spec['probe_level']} at the truth", nonlinearity[i, j]))
    return pd.DataFrame(rows, columns=["chassaignac", "criterion", "where", "value"])


def rule_text(spec) -> str:
    """The rule in words, with the scene's bounds and levels."""
    crit = spec["criteria"]
    box = " × ".join(SHORT[p] for p in spec["box_parameters"])
    factors = ", ".join(f"{f:g}" for f in spec["box_factors"])
    return (f"the smallest c of the grid such that, at the truth and at every admissible corner of the box "
            f"{box} × {{{factors}}}: (a) min det F in {spec['det_F_posture']} is ≥ {crit['min_det_F']:g} on every "
            f"level up to {spec['reference']}; (b) d = max_i |M_i({spec['compare_level']})/M_i({spec['reference']}) − 1| "
            f"exceeds its value at the same point for the grid's largest c (whose back does not slide, so that what "
            f"is left of d is the meshes' own gap) by at most {crit['max_sliding_difference']:g}; and (c) at the truth on {spec['probe_level']}, the uniqueness probe "
            f"(cold solves at Λ (1 ± {spec['epsilon']:g} e_j)) is linear, nonlinearity ≤ "
            f"{crit['linear_threshold']:g}, for all six parameters")


# -- report ---------------------------------------------------------------------------
