"""The Chassaignac calibration scene (issue #18): its stage jobs, summary, plan and config."""

import copy
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import yaml

from breastcore.model.parameters import Parameters
from breastcore.model.sliding import slip_threshold
from breastcore.pipeline.config import validate_config
from breastcore.pipeline.config_files import ConfigError

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = ROOT / "workflow/schemas/config.schema.yaml"
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")


# -- the stage jobs and the summary on coarse -----------------------------------------------
TINY_SCENE = {"kind": "calibration", "grid": [1000.0, 100.0], "levels": ["coarse"], "reference": "medium",
              "compare_level": "coarse", "jacobian_level": "coarse", "probe_level": "coarse",
              "postures": ["standing", "fours"], "box_parameters": ["H"], "box_factors": [0.9, 1.3],
              "identify_meshes": []}


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory):
    """Every job of a tiny calibration scene run through its stage function, then the summary."""
    from breastcore.pipeline.plan import Plan
    from breastcore.report.calibration import calibration_summary
    from breastcore.stages.calibrate import run_calibrate
    from breastcore.stages.mesh import run_mesh
    from breastcore.stages.uniqueness import run_uniqueness

    results = tmp_path_factory.mktemp("calibration") / "results"
    config = validate_config({"results": str(results), "scenes": {"cal": copy.deepcopy(TINY_SCENE)}}, SCHEMA)
    plan = Plan(config)
    for path, spec in plan.jobs["mesh"].items():
        run_mesh(spec, path)
    for path, spec in plan.jobs["calibrate"].items():
        run_calibrate(spec, spec["mesh"], path)
    for path, spec in plan.jobs["uniqueness"].items():
        run_uniqueness(spec, spec["mesh"], path)
    assert not plan.jobs["identify"] and not plan.jobs["solve"]      # identify_meshes: []
    return plan, calibration_summary(plan.scene("cal"), "cal")


def _direct(level, c, posture, params=None):
    """A cold solve of our own on the level's mesh, measured: (15-value row, min det F)."""
    from breastcore.forward.model import ForwardModel
    from breastcore.inverse.measurements import QUANTITIES, measure
    from breastcore.model.mesh import mesh_level
    from breastcore.model.postures import parse_posture
    model = ForwardModel(mesh_level(level))
    solution = model.solve((params or Parameters()).replace(chassaignac=c), parse_posture(posture))
    values = measure(model.mesh, solution.position)
    return np.array([values[q] for q in QUANTITIES]), solution.min_det_F


def test_the_summary_residual_is_that_of_direct_solves(tiny_study):
    plan, ds = tiny_study
    assert list(ds["chassaignac"].values) == [100.0, 1000.0]       # sorted
    assert list(ds["point"].values) == ["truth", "H×0.9", "H×1.3"]
    residuals = {}
    for c in (100.0, 1000.0):
        coarse = [_direct("coarse", c, p) for p in ("standing", "fours")]
        medium = [_direct("medium", c, p) for p in ("standing", "fours")]
        ratio = np.array([a[0] for a in coarse]) / np.array([m[0] for m in medium]) - 1
        residuals[c] = float(np.mean(ratio**2))
        assert float(ds["table2_residual"].sel(chassaignac=c, table2_level="coarse")) == \
            pytest.approx(residuals[c], rel=1e-9)
        assert float(ds["measurement_difference"].sel(chassaignac=c, point="truth")) == \
            pytest.approx(np.abs(ratio).max(), rel=1e-9)
        assert float(ds["standing_min_det_F"].sel(chassaignac=c, level="coarse", point="truth")) == \
            pytest.approx(coarse[0][1], rel=1e-9)
    assert residuals[100.0] > 10 * residuals[1000.0]                # issue #18: c = 100 is far from converged
    # H×1.3 > R is no cap: recorded, not solved, left out of the rule
    assert list(ds["admissible"].values) == [1, 1, 0]
    assert set(ds["outcome"].sel(point="H×1.3").values.ravel()) == {"inadmissible"}
    assert np.isnan(ds["sliding_margin"].sel(point="H×1.3")).all()
    assert float(ds["sliding_margin"].sel(chassaignac=100.0, point="truth")) == \
        pytest.approx(100.0 / slip_threshold(Parameters()))


def test_the_summary_and_its_table_report_the_depth_behind_the_torso_plane(tiny_study):
    """c = 100 Pa (sliding): standing crosses the plane y = 0; the table names the deepest (level, point)."""
    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    from breastcore.model.postures import parse_posture
    from breastcore.report.calibration_page import calibration_table
    plan, ds = tiny_study
    solution = ForwardModel(mesh_level("medium")).solve(Parameters(chassaignac=100.0), parse_posture("standing"))
    depth = ds["torso_penetration"].sel(chassaignac=100.0, level="medium", point="truth", posture="standing")
    assert float(depth) == pytest.approx(solution.torso_penetration, rel=1e-9) and float(depth) > 1e-3
    column = calibration_table(ds)["max depth behind torso plane, mm (level, point)"]
    for i, c in enumerate(ds["chassaignac"].values):
        deepest = ds["torso_penetration"].sel(chassaignac=c).isel(point=[0, 1]).max("posture")   # admissible
        where = np.unravel_index(int(np.argmax(deepest.values)), deepest.shape)
        expected = f"{1e3 * float(deepest.max()):.3g} ({deepest['level'].values[where[0]]}, " \
                   f"{deepest['point'].values[where[1]]})"
        assert column[i] == expected
    unrecorded = calibration_table(ds.drop_vars("torso_penetration"))     # a summary of older level datasets
    assert set(unrecorded["max depth behind torso plane, mm (level, point)"]) == {"not recorded"}


def test_a_level_dataset_without_the_depth_reads_nan_there_only(tiny_study, tmp_path):
    """Level datasets written before the depth was recorded: NaN in their cells, the others kept."""
    import xarray as xr

    from breastcore.io.datasets import write_netcdf
    from breastcore.report.calibration import calibration_summary
    plan, ds = tiny_study
    spec = copy.deepcopy(plan.scene("cal"))
    case = next(k for k, c in enumerate(spec["cases"]) if c["chassaignac"] == 100.0)
    with xr.open_dataset(spec["cases"][case]["levels"]["coarse"]) as old:
        older = old.load().drop_vars("torso_penetration")
    spec["cases"][case]["levels"]["coarse"] = str(write_netcdf(older, tmp_path / "older.nc"))
    depth = calibration_summary(spec, "cal")["torso_penetration"]
    assert np.isnan(depth.sel(chassaignac=100.0, level="coarse")).all()
    np.testing.assert_array_equal(depth.sel(chassaignac=100.0, level="medium"),
                                  ds["torso_penetration"].sel(chassaignac=100.0, level="medium"))


def test_the_summary_applies_the_rule_to_its_own_numbers(tiny_study):
    plan, ds = tiny_study
    criteria = list(ds["criterion"].values)
    for i, c in enumerate(ds["chassaignac"].values):
        det = ds["standing_min_det_F"].values[i][:, :2]             # every level, the admissible points
        linear = ds["nonlinearity"].values[i]
        expected = {"min_det_F": bool(np.all(det >= 0.01)),
                    "sliding_difference": bool(np.all(ds["sliding_difference"].values[i][:2] <= 0.01)),
                    "nonlinearity": bool(np.all(linear <= 1e-8))}
        assert dict(zip(criteria, ds["criterion_passed"].values[i].astype(bool))) == expected
        stiffest = ds["measurement_difference"].values[np.argmax(ds["chassaignac"].values)]
        np.testing.assert_allclose(ds["sliding_difference"].values[i], ds["measurement_difference"].values[i] - stiffest)
    passed = ds["chassaignac"].values[ds["passed"].values.astype(bool)]
    chosen = float(ds.attrs["chosen_chassaignac"])
    assert (chosen == passed.min()) if passed.size else np.isnan(chosen)
    assert float(ds.attrs["min_det_F"]) == 0.01 and "smallest c" in ds.attrs["rule"]


def test_the_summary_stores_each_identification_s_fit_verdict_beside_its_success(tmp_path):
    """The optimiser's success (1 for all three runs here) is not what an estimate is worth."""
    import xarray as xr

    from breastcore.io.datasets import provenance, write_netcdf
    from breastcore.report.calibration import _identification_variables
    verdicts = [["consistent", "misfit"], ["not_converged", "consistent"]]       # (c, start), on medium
    cases = []
    for i, row in enumerate(verdicts):
        runs = []
        for start, verdict in enumerate(row):
            ds = xr.Dataset({"relative_error": ("parameter", np.full(6, 0.01 * (start + 1))),
                             "wall_time": ("iteration", [0.0, 1.5]), "cost": ("iteration", [1.0, 1e-3])})
            for variable in ds.variables.values():
                variable.attrs.update(units="1", long_name="made up for the test")
            ds.attrs = provenance("identify", None, None, success=int(verdict != "not_converged"), verdict=verdict,
                                  iterations=1)
            path = write_netcdf(ds, tmp_path / f"id_{i}_{start}.nc")
            runs.append({"mesh": "medium", "start": start, "identification": str(path)})
        cases.append({"runs": runs})
    variables = _identification_variables({"identify_meshes": ["medium"], "starts": 2, "cases": cases})
    summary = xr.Dataset(variables)
    verdict = summary["identification_verdict"]
    assert verdict.dims == summary["identification_success"].dims == ("chassaignac", "identify_mesh", "start")
    assert verdict.values[:, 0].tolist() == verdicts
    assert summary["identification_success"].values[:, 0].tolist() == [[1, 1], [0, 1]]
    assert verdict.attrs["units"] == "1" and "fit verdict" in verdict.attrs["long_name"]


def test_the_uniqueness_probe_is_a_second_difference_of_cold_solves(tiny_study):
    from breastcore.io.datasets import open_dataset
    from breastcore.model.parameters import IDENTIFIED
    plan, ds = tiny_study
    path, spec = next((p, s) for p, s in plan.jobs["uniqueness"].items() if s["constants"]["chassaignac"] == 1000.0)
    probe = open_dataset(path)
    assert probe.attrs["stage"] == "uniqueness" and probe.attrs["epsilon"] == 1e-6
    j = IDENTIFIED.index("mu_breast")
    base = Parameters(chassaignac=1000.0)
    rows = [np.concatenate([_direct("coarse", 1000.0, p, base.replace(mu_breast=base.mu_breast * f))[0]
                            for p in ("standing", "fours")]) for f in (1 - 1e-6, 1.0, 1 + 1e-6)]
    minus, zero, plus = rows
    assert float(probe["nonlinearity"][j]) == pytest.approx(np.max(np.abs((plus - zero) - (zero - minus)) / zero),
                                                            rel=1e-6, abs=1e-15)
    assert float(probe["first_difference"][j]) == pytest.approx(np.max(np.abs(plus - minus) / (2 * zero)), rel=1e-6)
    assert 1e-9 < float(probe["first_difference"][j]) < 1e-5                  # a change of order ε, not 0
    np.testing.assert_array_equal(ds["nonlinearity"].sel(chassaignac=1000.0).values, probe["nonlinearity"].values)


def test_a_failed_solve_is_recorded_with_its_diagnostics_and_the_job_goes_on(monkeypatch):
    from breastcore.forward.model import ForwardModel
    from breastcore.forward.records import SolveError
    from breastcore.model.mesh import mesh_level
    from breastcore.model.postures import parse_posture
    from breastcore.studies.calibration import level_points_dataset
    model = ForwardModel(mesh_level("coarse"))
    real = ForwardModel.solve

    def failing(self, params, posture, start=None):              # the standing solve at μ × 0.5 fails
        if posture.name == "standing" and params.mu_breast < 100:
            raise SolveError("continuation stalled", iterations=7, gradient_norm=1e-3, tolerance=1e-9,
                             min_det_F=2e-6, load_factor=0.4, smoothing=1e-4, posture="standing")
        return real(self, params, posture, start)

    monkeypatch.setattr(ForwardModel, "solve", failing)
    truth = Parameters().as_dict()
    points = [{k: truth[k] for k in ("R", "H", "lambda_breast", "mu_breast", "lambda_skin", "mu_skin")}]
    points.append({**points[0], "mu_breast": 75.0})
    ds = level_points_dataset(model, "coarse", ["truth", "μ×0.5"], points, {"chassaignac": 300.0},
                              [parse_posture("standing"), parse_posture("fours")])
    assert ds["outcome"].values.tolist() == [["converged", "converged"], ["solve_error", "converged"]]
    assert float(ds["min_det_F"][1, 0]) == 2e-6 and float(ds["load_factor"][1, 0]) == 0.4
    assert "continuation stalled" in str(ds["message"].values[1, 0])
    assert np.isnan(ds["measurement"][1, 0]).all() and np.isfinite(ds["measurement"][1, 1]).all()
    assert np.isfinite(ds["singular_value"]).all() and ds["singular_value"].values[0] >= ds["singular_value"].values[-1]


@pytest.mark.parametrize("job", ["calibrate", "uniqueness"])
def test_an_inadmissible_first_point_is_refused_not_stored_as_the_default_parameters(job):
    """The problem spec of the dataset held Parameters(**constants), the default Λ, not the point."""
    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import IDENTIFIED, ParameterError
    from breastcore.model.postures import parse_posture
    from breastcore.studies.calibration import level_points_dataset, uniqueness_dataset
    truth = Parameters().as_dict()
    bad = {**{k: truth[k] for k in IDENTIFIED}, "H": 2 * truth["R"]}        # H ≥ R: no cap
    model, postures = ForwardModel(mesh_level("coarse")), [parse_posture("standing"), parse_posture("fours")]
    with pytest.raises(ParameterError, match="first point, .*, is not admissible"):
        if job == "calibrate":
            level_points_dataset(model, "coarse", ["truth"], [bad], {"chassaignac": 300.0}, postures)
        else:
            uniqueness_dataset(model, "coarse", bad, {"chassaignac": 300.0}, postures)


# -- config ---------------------------------------------------------------------------------
def _scene_error(**changes):
    scene = {**copy.deepcopy(TINY_SCENE), **changes}
    with pytest.raises(ConfigError) as info:
        validate_config({"scenes": {"cal": scene}}, SCHEMA)
    return str(info.value)


@pytest.mark.parametrize("grid, message", [
    ([-100.0], r"scenes\.cal\.grid\.0: -100\.0 is less than or equal to the minimum of 0"),
    ([0.0, 300.0], r"scenes\.cal\.grid\.0: 0\.0 is less than or equal to the minimum of 0"),
    ([], r"scenes\.cal\.grid: \[\] should be non-empty"),
    ([300.0, 300.0], r"scenes\.cal\.grid: .*non-unique"),
    (["1e3"], r"scenes\.cal\.grid\.0: '1e3' is not of type 'number'.*write 1\.0e\+3"),
    ([float("inf")], r"scenes\.cal\.grid\[0\]: inf is not a finite number"),
    (300.0, r"scenes\.cal\.grid: 300\.0 is not of type 'array'"),
])
def test_bad_grid_values_are_refused_naming_the_key(grid, message):
    assert re.search(message, _scene_error(grid=grid)), _scene_error(grid=grid)


@pytest.mark.parametrize("changes, message", [
    ({"levels": ["coarse", "medium"], "reference": "medium"}, "scenes.cal.levels: lists the reference level 'medium'"),
    ({"compare_level": "thin"}, "scenes.cal.compare_level: 'thin' is not one of levels"),
    ({"probe_level": "fine"}, "scenes.cal.probe_level: unknown mesh level 'fine'"),
    ({"det_F_posture": "bent45"}, "scenes.cal.det_F_posture: 'bent45' is not one of postures"),
    ({"box_parameters": ["R", "volume"]}, "scenes.cal.box_parameters.1: 'volume' is not one of"),
    ({"min_det_F": 2.0}, "scenes.cal.min_det_F: 2.0 is greater than the maximum of 1"),
    ({"truth": {"R": 0.05, "H": 0.06}}, "scenes.cal.truth.H: H = 0.06 m must be < R = 0.05 m"),
    ({"colour": "red"}, "scenes.cal: unknown key: 'colour'"),
])
def test_bad_calibration_keys_are_refused_naming_the_key(changes, message):
    assert message in _scene_error(**changes)


def test_the_defaults_are_the_issue_s_study():
    scene = validate_config({"scenes": {"c": {"kind": "calibration"}}}, SCHEMA)["scenes"]["c"]
    assert scene["grid"] == [100.0, 200.0, 300.0, 500.0, 700.0, 1000.0, 2000.0, 5000.0]
    assert scene["levels"] == ["coarse", "medium", "medium-thin", "thin", "very-thin", "ultra-thin"]
    assert (scene["reference"], scene["compare_level"], scene["probe_level"], scene["jacobian_level"]) == \
        ("reference", "very-thin", "thin", "medium")
    assert (scene["min_det_F"], scene["max_sliding_difference"], scene["linear_threshold"]) == (0.01, 0.01, 1e-8)
    assert scene["identification"]["max_iterations"] == 25 and scene["identification"]["cost_rtol"] == 0.01
    assert scene["identification"]["method"] == "lm" and scene["identify_meshes"] == ["medium", "very-thin"]
    assert scene["truth"]["R"] == 0.0562 and scene["box_factors"] == [0.7, 1.3]


def test_the_calibration_config_plans_its_scene_and_nothing_else(tmp_path):
    """A dry run from an empty folder of config.yaml plus config/calibration.yaml."""
    (tmp_path / "config.yaml").write_text((ROOT / "config.yaml").read_text())
    out = subprocess.run([SNAKEMAKE, "-s", str(ROOT / "Snakefile"), "-d", str(tmp_path), "--cores", "2", "-n",
                          "--configfile", str(ROOT / "config/calibration.yaml")], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    jobs = [(block.split(":", 1)[0], (re.findall(r"^    output: (.*)$", block, re.M) or [""])[0])
            for block in re.split(r"^(?:local)?rule ", out.stdout, flags=re.M)[1:]]
    # an identification job is rule identify, or a batch of several (identify_batch_<key>): count identifications
    rules = Counter(rule for rule, _ in jobs if not rule.startswith("identify"))
    rules["identify"] = sum(len(output.split(", ")) for rule, output in jobs if rule.startswith("identify"))
    scene = yaml.safe_load((ROOT / "config/calibration.yaml").read_text())["scenes"]["calibration"]
    c, levels, runs = len(scene["grid"]), len(scene["levels"]) + 1, len(scene["identify_meshes"]) * scene["starts"]
    # per c: a calibrate job per level and the reference, a probe, the truth solve, its
    # measurements and the identifications; the meshes (each level, and the truth's by gmsh)
    assert rules == Counter({"calibrate": c * levels, "uniqueness": c, "solve": c, "measure": c, "identify": c * runs,
                             "mesh": levels + 1, "scene_summary": 1, "calibration_figure": 1, "report_front_page": 1,
                             "all": 1})
    outputs = re.findall(r"^    output: (.*)$", out.stdout, re.M)
    assert all(o.startswith(("results/calibrate/", "results/uniqueness/", "results/solve/", "results/measure/",
                             "results/identify/", "results/mesh/", "results/scenes/calibration/",
                             "results/report/front.html")) for o in outputs)
    assert not any("example_patient" in o or "paper_synthetic" in o for o in outputs)


def _merged(*files):
    """config.yaml with the opt-in files merged in (Snakemake's deep merge), checked, nulls dropped and
    validated, as the Snakefile does."""
    from breastcore.pipeline.overlays import _merge, check_overlays, drop_keys
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    for name in files:
        config = _merge(config, yaml.safe_load((ROOT / name).read_text()))
    drop_keys(config, check_overlays(ROOT / "config.yaml", [ROOT / name for name in files], False, SCHEMA))
    return validate_config(config, SCHEMA)


def test_at_the_constants_c_the_identifications_are_the_paper_table1_jobs():
    from breastcore.pipeline.plan import Plan
    config = _merged("config/paper.yaml", "config/calibration.yaml")
    plan = Plan(config)
    ours = plan.scene("calibration")["cases"]
    same_c = next(case for case in ours if case["chassaignac"] == config["constants"]["chassaignac"])
    table1 = {(r["mesh"], r["offset"], r["start"]): r["identification"] for r in plan.scene("paper_table1")["runs"]}
    assert [run["identification"] for run in same_c["runs"]] == \
        [table1[(run["mesh"], 0.3, run["start"])] for run in same_c["runs"]]
    other = next(case for case in ours if case["chassaignac"] != config["constants"]["chassaignac"])
    assert not {run["identification"] for run in other["runs"]} & set(table1.values())
    assert {plan.jobs["identify"][run["identification"]]["constants"]["chassaignac"] for run in other["runs"]} == \
        {other["chassaignac"]}


def test_the_rule_s_bounds_are_not_in_any_job_spec():
    """Changing a bound reruns only the summary and its figure: every job path stays."""
    from breastcore.pipeline.plan import Plan
    config = _merged("config/calibration.yaml")
    changed = copy.deepcopy(config)
    changed["scenes"]["calibration"].update(min_det_F=0.001, max_sliding_difference=0.02, linear_threshold=1e-6)
    before, after = Plan(config), Plan(changed)
    for stage in ("calibrate", "uniqueness", "solve", "measure", "identify", "mesh"):
        assert before.jobs[stage].keys() == after.jobs[stage].keys(), stage
    assert before.scene("calibration")["criteria"] != after.scene("calibration")["criteria"]
