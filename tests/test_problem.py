"""One problem definition through every stage: each stage dataset records the ProblemSpec it was
computed with, and every later stage rebuilds exactly that problem (issue #17)."""

import dataclasses

import numpy as np
import pytest

from breastcore.forward.options import SolverOptions
from breastcore.inverse import sensitivity as sensitivity_module
from breastcore.inverse.operator import MeasurementModel
from breastcore.inverse.options import IdentificationOptions
from breastcore.io.datasets import mesh_dataset, open_dataset, write_netcdf
from breastcore.io.rebuild import model_mesh_from_identification, problem_from_identification
from breastcore.io.solution import equilibrium_residual
from breastcore.model.mesh import LEVEL_MESH_SIZE, mesh_level
from breastcore.model.parameters import IDENTIFIED, Parameters
from breastcore.model.postures import Posture, paper_postures
from breastcore.problem import ProblemSpec, ProblemSpecError
from breastcore.stages.calibrate import run_calibrate
from breastcore.stages.extreme import run_extreme_guesses
from breastcore.stages.identify import run_identify
from breastcore.stages.measure import run_measure
from breastcore.stages.sensitivity import run_sensitivity
from breastcore.stages.solve import run_solve
from breastcore.stages.stability import run_stability
from breastcore.stages.uniqueness import run_uniqueness

#: Non-default constants, solver options and identification options: none may be replaced by a default.
CONSTANTS = dict(skin_thickness=1.2e-3, density=1010.0, gravity_magnitude=9.8, chassaignac=300.0, smoothing=1e-5,
                 fold_angle=170.0)
SOLVER = dict(method="newton", rtol=1e-7, stage_rtol=2e-5, smoothing_start=2e-4, max_iterations=90,
              min_step=1 / 128, cg_max_iterations=15000, max_extensions=3, max_final_attempts=2,
              reuse_factor=0.25, sliding_dual=False, sliding_release=False, inertia_shift=False,
              mixed_precision_min_dofs=5000, step_rtol=1e-4, skip_futile_shifts=False, deep_indefinite_skips=2)
IDENTIFICATION = dict(method="lm", jacobian="implicit", fd_step=2e-4, cost_tol=1e-13, cost_rtol=0.01, xtol=1e-7,
                      ftol=1e-7, gtol=1e-9, max_iterations=3, noise=0.05, initial_trust_radius=0.4,
                      fixed_iterations=False, warm_radius=0.07, reduced_snapshots=3, tangent_starts=False)
POSTURES = [{"name": "standing", "angle": 0.0}, {"name": "lean", "angle": 30.0}, {"name": "fours", "angle": 90.0}]


def non_default_spec():
    return ProblemSpec(parameters=Parameters(**CONSTANTS, R=0.06, H=0.045, mu_breast=170.0),
                       solver=SolverOptions(**SOLVER), postures=tuple(Posture(**p) for p in POSTURES),
                       measurement_set="exact", identification=IdentificationOptions(**IDENTIFICATION))


def test_every_option_of_the_fixture_differs_from_its_default():
    """The round trips below can only catch a fallback to a default if no field is at its default."""
    spec = non_default_spec()
    for options, default in ((spec.solver, SolverOptions()), (spec.identification, IdentificationOptions())):
        same = [f.name for f in dataclasses.fields(options) if getattr(options, f.name) == getattr(default, f.name)]
        assert same in ([], ["method"], ["method", "jacobian", "fixed_iterations"])
    constants = [k for k in CONSTANTS if getattr(spec.parameters, k) == getattr(Parameters(), k)]
    assert constants == []


def test_spec_round_trips_through_json():
    spec = non_default_spec()
    assert ProblemSpec.from_json(spec.to_json()) == spec
    bare = ProblemSpec()
    assert ProblemSpec.from_json(bare.to_json()) == bare


@pytest.mark.parametrize("edit", ["drop_solver_field", "extra_field", "drop_identification_field", "drop_top"])
def test_a_spec_with_missing_or_unknown_fields_is_refused_not_defaulted(edit):
    data = non_default_spec().as_dict()
    if edit == "drop_solver_field":
        del data["solver"]["rtol"]
    elif edit == "extra_field":
        data["parameters"]["viscosity"] = 1.0
    elif edit == "drop_identification_field":
        del data["identification"]["warm_radius"]
    else:
        del data["measurement_set"]
    with pytest.raises(ProblemSpecError):
        ProblemSpec.from_dict(data)


def test_a_spec_written_before_reuse_factor_reads_with_the_method_of_then():
    """Datasets written before the chord-step option have no ``reuse_factor``: they were computed
    with a fresh factorisation every iteration, which is reuse_factor 0, whatever today's value."""
    spec = non_default_spec()
    data = spec.as_dict()
    del data["solver"]["reuse_factor"]
    read = ProblemSpec.from_dict(data)
    assert read.solver.reuse_factor == 0.0 and spec.solver.reuse_factor != 0.0
    assert read == dataclasses.replace(spec, solver=dataclasses.replace(spec.solver, reuse_factor=0.0))


def test_a_spec_written_before_the_step_options_reads_with_the_exact_hessian_and_the_projection():
    """Datasets written before ``sliding_dual``, ``inertia_shift`` and ``mixed_precision_min_dofs`` were
    computed with neither option and single precision from 100,000 dofs on."""
    spec = non_default_spec()
    spec = dataclasses.replace(spec, solver=dataclasses.replace(spec.solver, sliding_dual=True, inertia_shift=True))
    data = spec.as_dict()
    del data["solver"]["sliding_dual"], data["solver"]["inertia_shift"], data["solver"]["mixed_precision_min_dofs"]
    read = ProblemSpec.from_dict(data)
    assert read == dataclasses.replace(spec, solver=dataclasses.replace(
        spec.solver, sliding_dual=False, inertia_shift=False, mixed_precision_min_dofs=100_000))
    assert spec.solver.sliding_dual and spec.solver.inertia_shift


def test_a_spec_written_before_the_inexact_steps_reads_with_refined_steps_and_every_shift():
    """Datasets written before ``step_rtol`` and ``skip_futile_shifts`` refined every Newton
    direction to 1e-10 and tried the inertia shifts at every indefinite step."""
    spec = non_default_spec()
    spec = dataclasses.replace(spec, solver=dataclasses.replace(spec.solver, skip_futile_shifts=True))
    data = spec.as_dict()
    del data["solver"]["step_rtol"], data["solver"]["skip_futile_shifts"]
    read = ProblemSpec.from_dict(data)
    assert read == dataclasses.replace(spec, solver=dataclasses.replace(
        spec.solver, step_rtol=1e-10, skip_futile_shifts=False))
    assert spec.solver.step_rtol == 1e-4 and spec.solver.skip_futile_shifts


@pytest.mark.parametrize("section, field, now, then", [
    ("identification", "tangent_starts", True, False),      # far solves started without the predictor
    ("solver", "sliding_release", True, False),             # the primal-dual sliding blocks alone
    ("solver", "deep_indefinite_skips", 3, 0),              # an exact factorisation at every fresh step
])
def test_a_spec_written_before_an_option_reads_with_the_method_of_then(section, field, now, then):
    """Datasets written before ``tangent_starts``, ``sliding_release`` or ``deep_indefinite_skips`` were
    computed without them."""
    spec = non_default_spec()
    spec = dataclasses.replace(spec, **{section: dataclasses.replace(getattr(spec, section), **{field: now})})
    data = spec.as_dict()
    del data[section][field]
    read = ProblemSpec.from_dict(data)
    assert read == dataclasses.replace(spec, **{section: dataclasses.replace(getattr(spec, section), **{field: then})})
    assert getattr(getattr(spec, section), field) == now


@pytest.mark.parametrize("field, other", [("warm_radius", 0.05), ("reduced_snapshots", 8), ("tangent_starts", True)])
def test_check_model_refuses_a_measurement_model_built_with_other_identification_options(field, other):
    spec = non_default_spec()
    mm = MeasurementModel.from_problem(spec, mesh_level("coarse"))
    spec.check_model(mm)                                          # the model the spec builds passes
    assert getattr(mm, field) != other
    setattr(mm, field, other)
    with pytest.raises(ProblemSpecError, match=field):
        spec.check_model(mm)


def test_a_dataset_without_a_spec_names_its_stage():
    import xarray as xr
    with pytest.raises(ProblemSpecError, match="stage 'identify'"):
        ProblemSpec.from_dataset(xr.Dataset(attrs={"stage": "identify"}))


def test_a_spec_without_identification_options_has_no_warm_radius_not_the_default_one():
    """Only identification options define the warm-start radius: no fallback to IdentificationOptions()."""
    assert non_default_spec().warm_radius() == 0.07
    bare = non_default_spec().replace(identification=None)
    with pytest.raises(ProblemSpecError, match="no identification options"):
        bare.warm_radius()
    with pytest.raises(ProblemSpecError, match="warm_radius"):
        MeasurementModel.from_problem(bare, mesh_level("coarse"))


@pytest.fixture(scope="module")
def stages(tmp_path_factory):
    """Every stage run once on coarse with the non-default spec: ``{stage: dataset path}``."""
    folder = tmp_path_factory.mktemp("stages")
    spec = non_default_spec()
    mesh_path = write_netcdf(mesh_dataset(mesh_level("coarse"), "coarse", LEVEL_MESH_SIZE["coarse"]),
                             folder / "mesh.nc")
    truth = {k: getattr(Parameters(), k) for k in IDENTIFIED}
    paths = {"solve": folder / "solve.nc", "measure": folder / "measure.nc", "identify": folder / "identify.nc",
             "sensitivity": folder / "sensitivity.nc", "stability": folder / "stability.nc",
             "extreme": folder / "extreme.nc", "calibrate": folder / "calibrate.nc",
             "uniqueness": folder / "uniqueness.nc"}
    run_solve({"parameters": {**CONSTANTS, **truth}, "postures": POSTURES, "solver": SOLVER}, mesh_path,
              paths["solve"])
    run_measure({"measurement_set": "exact", "noise": 0.0, "seed": 0}, paths["solve"], paths["measure"])
    initial = {k: v * 1.05 for k, v in truth.items()}
    run_identify({"initial": initial, "constants": CONSTANTS, "solver": SOLVER, "identification": IDENTIFICATION},
                 paths["measure"], mesh_path, paths["identify"])
    run_sensitivity({"finite": False, "delta": 0.1}, paths["identify"], paths["sensitivity"])
    run_stability({"level": "coarse", "constants": CONSTANTS, "solver": SOLVER,
                   "cases": [{"lam_over_mu": 6.7, "mu": 150.0, "mu_s": 1600.0, "H_over_R": 0.89, "c": 300.0,
                              "delta": 1e-5, "posture": "fours"}]}, mesh_path, paths["stability"])
    run_extreme_guesses({"level": "coarse", "factors": [4.0], "constants": CONSTANTS, "solver": SOLVER,
                         "identification": {**IDENTIFICATION, "max_iterations": 1}}, mesh_path, paths["extreme"])
    point = {k: getattr(spec.parameters, k) for k in IDENTIFIED}          # R, H and μ not at their defaults
    calibration = {"constants": CONSTANTS, "solver": SOLVER, "postures": POSTURES[1:2], "measurement_set": "exact"}
    run_calibrate({**calibration, "level": "coarse", "points": [{"label": "truth", "parameters": point}]},
                  mesh_path, paths["calibrate"])
    run_uniqueness({**calibration, "truth": point, "epsilon": 1e-5}, mesh_path, paths["uniqueness"])
    return spec, paths


def test_solve_dataset_records_the_spec_it_was_solved_with(stages):
    spec, paths = stages
    recorded = ProblemSpec.from_dataset(open_dataset(paths["solve"]))
    assert recorded == spec.replace(parameters=Parameters(**CONSTANTS), measurement_set=None, identification=None)
    g, tolerance = equilibrium_residual(open_dataset(paths["solve"]), "lean")
    assert g <= tolerance                                       # checked with the recorded rtol 1e-7
    assert tolerance == pytest.approx(1e-7 / 1e-8 * equilibrium_tolerance_default(paths["solve"]), rel=1e-12)


def equilibrium_tolerance_default(path):
    """The tolerance the default rtol would give: the residual check must not use it."""
    ds = open_dataset(path)
    spec = ProblemSpec.from_dataset(ds)
    from breastcore.io.datasets import mesh_from_dataset
    model = spec.replace(solver=SolverOptions()).forward_model(mesh_from_dataset(ds))
    return model.tolerance(spec.parameters, spec.postures[1])


def test_measure_dataset_records_the_truth_problem_and_its_measurement_set(stages):
    spec, paths = stages
    recorded = ProblemSpec.from_dataset(open_dataset(paths["measure"]))
    assert recorded == spec.replace(parameters=Parameters(**CONSTANTS), identification=None)


def test_identification_records_and_rebuilds_exactly_its_problem(stages):
    spec, paths = stages
    ds = open_dataset(paths["identify"])
    recorded = ProblemSpec.from_dataset(ds)
    initial = Parameters(**CONSTANTS).with_identified(np.array(Parameters().identified()) * 1.05)
    assert recorded == spec.replace(parameters=initial)
    problem, mm, target, estimate = problem_from_identification(ds)
    assert problem == recorded
    problem.check_model(mm)
    assert mm.warm_radius == 0.07 and mm.model.options == SolverOptions(**SOLVER)
    assert mm.reduced_snapshots == 3 and mm.warm_starts().snapshots == 3
    assert mm.tangent_starts is False and mm.warm_starts().tangent_starts is False
    assert mm.base.chassaignac == 300.0 and mm.base.smoothing == 1e-5 and mm.measurement_set == "exact"
    np.testing.assert_array_equal(mm.model.mesh.nodes, mesh_level("coarse").nodes)   # node for node
    np.testing.assert_array_equal(estimate, ds["estimate"].values)
    np.testing.assert_array_equal(target.values, ds["target"].values)


def test_the_rebuilt_mesh_is_the_model_mesh_not_the_displayed_one(stages):
    _, paths = stages
    ds = open_dataset(paths["identify"])
    rebuilt = model_mesh_from_identification(ds)
    assert not np.array_equal(ds["reference_position"].values, rebuilt.nodes)   # shown at the estimate's R, H
    assert (rebuilt.R, rebuilt.H) == (mesh_level("coarse").R, mesh_level("coarse").H)


@pytest.mark.parametrize("stage", ["sensitivity", "stability", "extreme", "calibrate", "uniqueness"])
def test_later_stages_record_their_spec(stages, stage):
    spec, paths = stages
    ds = open_dataset(paths[stage])
    recorded = ProblemSpec.from_dataset(ds)
    if stage == "sensitivity":
        assert recorded == ProblemSpec.from_dataset(open_dataset(paths["identify"]))
    elif stage == "stability":
        assert recorded == ProblemSpec(parameters=Parameters(**CONSTANTS), solver=SolverOptions(**SOLVER),
                                       postures=(Posture("fours", 90.0),))
    elif stage == "extreme":
        # documented: the truth Λ̄ of the constants, the paper's postures and measurement set
        assert recorded == spec.replace(parameters=Parameters(**CONSTANTS), postures=paper_postures(),
                                        measurement_set="paper15",
                                        identification=IdentificationOptions(**{**IDENTIFICATION,
                                                                                 "max_iterations": 1}))
    else:
        # the constants with the first point's (the truth's) Λ, the job's posture and measurement set; no options
        assert recorded == spec.replace(postures=(Posture("lean", 30.0),), identification=None)
        assert ds.attrs["chassaignac"] == 300.0 and ds.attrs["mesh_level"] == "coarse"
        if stage == "uniqueness":
            assert ds.attrs["epsilon"] == 1e-5


@pytest.mark.parametrize("via", ["stage", "cli"])
def test_finite_sensitivity_re_identifies_with_exactly_the_identification_problem(stages, monkeypatch, tmp_path, via):
    """Identified with c = 300 Pa, δ = 1e-5 m, rtol = 1e-7 and warm radius 0.07, every
    re-identification must run with those (it ran with 100, 1e-6, 1e-8 and 0.05), whether
    from the workflow stage or from ``breastcore sensitivity``."""
    spec, paths = stages
    seen = []

    def spy(mm, target, initial, options, weights=None, warm=None):
        seen.append((mm.base, mm.model.options, mm.warm_radius, mm.measurement_set, tuple(mm.postures), options,
                     mm.model.mesh.nodes.copy()))
        raise RuntimeError("recorded; not run")               # a failure is recorded, never fatal

    monkeypatch.setattr(sensitivity_module, "identify", spy)
    if via == "stage":
        run_sensitivity({"finite": True, "delta": 0.1}, paths["identify"], tmp_path / "s.nc")
    else:
        from breastcore.cli import main as cli
        assert cli.main(["sensitivity", str(paths["identify"]), "--delta", "0.1", "--out",
                         str(tmp_path / "s.nc")]) == 0
    recorded = ProblemSpec.from_dataset(open_dataset(paths["identify"]))
    assert len(seen) == 2 * 15
    for base, solver, radius, measurement_set, postures, options, nodes in seen:
        assert base == recorded.parameters and base.chassaignac == 300.0 and base.smoothing == 1e-5
        assert solver == recorded.solver and solver.rtol == 1e-7
        assert radius == 0.07 and measurement_set == "exact" and postures == spec.postures
        assert options == recorded.identification
        np.testing.assert_array_equal(nodes, mesh_level("coarse").nodes)
    assert ProblemSpec.from_dataset(open_dataset(tmp_path / "s.nc")) == recorded
