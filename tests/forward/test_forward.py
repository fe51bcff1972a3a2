"""Forward solves: equilibrium recomputed from the saved dataset, warm starts,
the CG baseline at the same tolerance, and typed failures with diagnostics."""

import dataclasses

import numpy as np
import pytest

from breastcore.cli.main import main
from breastcore.fem.loads import Gravity
from breastcore.forward.model import ForwardModel
from breastcore.forward.options import SolverOptions
from breastcore.forward.records import SolveError
from breastcore.io.datasets import open_dataset
from breastcore.io.solution import equilibrium_residual
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import Posture


@pytest.fixture(scope="module")
def coarse():
    return mesh_level("coarse")


@pytest.mark.parametrize("level", ["coarse", "thin"])
def test_saved_solution_is_in_equilibrium(tmp_path, level):
    out = tmp_path / f"{level}.nc"
    assert main(["solve", "--mesh", level, "--out", str(out)]) == 0
    ds = open_dataset(out)
    assert list(ds["posture"].values) == ["standing", "bent45", "fours"]
    for name in ds["posture"].values:
        g_norm, tol = equilibrium_residual(ds, str(name))
        load = np.linalg.norm(ds["gravity"].sel(posture=name).values)
        assert tol == pytest.approx(1e-8 * tol / 1e-8) and tol > 0 and load == pytest.approx(9.81)
        assert g_norm <= tol
    # the breast sags: standing moves the nipple down, on all fours forward
    nipple = int(ds["landmark_node"].sel(landmark="nipple"))
    u = ds["position"][:, nipple] - ds["reference_position"][nipple]
    assert float(u.sel(posture="standing", xyz="z")) < -0.02
    assert float(u.sel(posture="fours", xyz="y")) > 0.005


def test_tolerance_is_relative_to_gravity_load(coarse):
    model = ForwardModel(coarse)
    p = Parameters()
    load = model.problem(p, Posture("standing", 0.0)).gravity.load
    assert model.tolerance(p, Posture("standing", 0.0)) == pytest.approx(1e-8 * np.linalg.norm(load))


def test_warm_start_after_small_change_is_cheap(coarse):
    model = ForwardModel(coarse)
    p = Parameters()
    posture = Posture("standing", 0.0)
    cold = model.solve(p, posture)
    changed = p.with_identified([v * 1.01 for v in p.identified()])
    warm = model.solve(changed, posture, start=cold.position)
    assert warm.converged and warm.gradient_norm <= warm.tolerance
    assert warm.iterations < cold.iterations
    assert warm.continuation_steps == 1


def test_cg_baseline_reaches_the_same_tolerance(coarse):
    p = Parameters()
    posture = Posture("bent45", 45.0)
    newton = ForwardModel(coarse).solve(p, posture)
    cg = ForwardModel(coarse, SolverOptions(method="cg")).solve(p, posture)
    assert cg.gradient_norm <= cg.tolerance == pytest.approx(newton.tolerance)
    nipple = coarse.landmarks["nipple"]
    assert np.allclose(cg.position[nipple], newton.position[nipple], atol=1e-4)


def test_failure_raises_typed_error_with_diagnostics(coarse):
    model = ForwardModel(coarse, SolverOptions(max_iterations=1, min_step=0.5))
    with pytest.raises(SolveError) as info:
        model.solve(Parameters(), Posture("standing", 0.0))
    err = info.value
    assert err.iterations >= 1 and err.gradient_norm > err.tolerance > 0
    assert np.isfinite(err.min_det_F) and 0 <= err.load_factor <= 1 and err.smoothing > 0
    assert "min det F" in str(err)


@pytest.mark.parametrize("breakdowns", [1, 10**6])
def test_a_numerical_breakdown_is_a_failed_step_never_a_bare_linalg_error(coarse, monkeypatch, breakdowns):
    """Very soft parameters degenerate an element until numpy's eigen-solve of its projected Hessian
    fails (``LinAlgError: Eigenvalues did not converge``), which reached the user without diagnostics.
    Now a breakdown is a failed continuation step: once, the step is halved and the solve converges;
    always, the solve ends in a SolveError with its diagnostics."""
    import breastcore.forward.continuation as continuation
    real, calls = continuation.newton, {"n": 0}

    def breaking(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] <= breakdowns:
            raise np.linalg.LinAlgError("Eigenvalues did not converge")
        return real(*args, **kwargs)

    monkeypatch.setattr(continuation, "newton", breaking)
    model = ForwardModel(coarse, SolverOptions(min_step=1e-3))
    posture = Posture("fours", 90.0)
    if breakdowns == 1:
        solution = model.solve(Parameters(), posture)
        problem = model.problem(Parameters(), posture)
        assert np.linalg.norm(problem.gradient(problem.free(solution.position))) <= solution.tolerance
        return
    with pytest.raises(SolveError) as info:
        model.solve(Parameters(), posture)
    err = info.value
    assert "numerical breakdown: Eigenvalues did not converge" in str(err) and err.posture == "fours"
    assert np.isfinite(err.gradient_norm) and np.isfinite(err.min_det_F) and err.tolerance > 0


@pytest.mark.parametrize("attempts", [1, 3])
def test_unreachable_tolerance_gives_up_after_max_final_attempts(coarse, attempts):
    # rtol 1e-20 is below the gradient's round-off floor: every final step stagnates,
    # while the intermediate steps (stage_rtol) converge. The final step is a δ step only
    # with a δ phase: the gravity ramp at smoothing_start = 1e-4 m above the target 1e-6 m.
    model = ForwardModel(coarse, SolverOptions(rtol=1e-20, max_final_attempts=attempts, smoothing_start=1e-4))
    with pytest.raises(SolveError) as info:
        model.solve(Parameters(), Posture("bent45", 45.0))
    err = info.value
    assert f"final step failed {attempts} times" in str(err)
    assert err.load_factor == 1.0 and err.gradient_norm > err.tolerance
    assert np.isfinite(err.min_det_F) and err.min_det_F > 0


def test_final_gravity_step_is_halved_to_min_step_not_capped(coarse):
    # δ = smoothing_start: no δ phase, the final step is the load step, which is halved
    # down to min_step (1/4 here) however many times it fails.
    model = ForwardModel(coarse, SolverOptions(rtol=1e-20, max_final_attempts=1, min_step=0.25))
    with pytest.raises(SolveError) as info:
        model.solve(Parameters(smoothing=1e-4), Posture("bent45", 45.0))
    assert "continuation stalled" in str(info.value)


def test_max_final_attempts_must_be_positive():
    with pytest.raises(ValueError, match="max_final_attempts"):
        SolverOptions(max_final_attempts=0)


def test_intermediate_posture_angle_lies_between_neighbours(coarse):
    model = ForwardModel(coarse)
    p = Parameters()
    nipple = coarse.landmarks["nipple"]
    z = [model.solve(p, Posture(f"a{int(a)}", a)).position[nipple, 2] for a in (0.0, 20.0, 45.0)]
    assert z[0] < z[1] < z[2]


def test_no_gravity_leaves_the_cap_at_rest(coarse):
    model = ForwardModel(coarse)
    sol = model.solve(Parameters(gravity_magnitude=0.0), Posture("standing", 0.0))
    assert np.allclose(sol.position, model.reference(Parameters().R, Parameters().H), atol=1e-12)


def test_energy_at_fixed_deformation_is_differentiable_in_R_and_H(coarse):
    """Through the smooth map, J(R, H; x) at a fixed deformed state has consistent central differences.

    The steps move the reference nodes by less than the Chassaignac smoothing δ = 1e-6 m (5.6e-9 and
    5.6e-10 m): a back node that sticks (|x − P| ≲ δ) has an energy that bends on the length δ, so
    steps of 1e-4 R and 1e-5 R (5.6 and 0.56 µm) gave slopes 20 % apart at c = 500 Pa."""
    model = ForwardModel(coarse)
    p = Parameters()
    posture = Posture("bent45", 45.0)
    x = model.solve(p, posture).position

    def energy(**change):
        return model.problem(p.replace(**change), posture).energy.value(x)

    for name in ("R", "H"):
        value = getattr(p, name)
        slopes = [(energy(**{name: value * (1 + h)}) - energy(**{name: value * (1 - h)})) / (2 * h * value)
                  for h in (1e-7, 1e-8)]
        assert np.isfinite(slopes).all() and abs(slopes[0]) > 0
        assert slopes[0] == pytest.approx(slopes[1], rel=1e-5)


def test_the_tolerance_is_rtol_times_the_problems_gravity_load_to_the_bit(coarse):
    """ForwardModel.tolerance takes only the gravity term; it must be the full problem's load norm,
    and that of a gravity term built from its constructor (not through the geometry cache)."""
    model = ForwardModel(coarse)
    for params in (Parameters(), Parameters(R=0.07, H=0.03, density=1100.0)):
        for posture in (Posture("standing", 0.0), Posture("lean", 30.0), Posture("fours", 90.0)):
            acceleration = posture.gravity(params.gravity_magnitude)
            fresh = Gravity(model.map.positions(params.R, params.H), coarse.tets, params.density, acceleration)
            load = np.linalg.norm(model.problem(params, posture).gravity.load)
            assert load == np.linalg.norm(fresh.load)
            assert model.tolerance(params, posture) == model.options.rtol * load


def test_without_a_delta_phase_a_failed_warm_start_falls_back_to_the_cold_solve(coarse, monkeypatch):
    """With δ = smoothing_start there is no δ to continue in from the start: the fallback is the
    cold continuation (re-solving the target from the same start would fail the same way)."""
    from breastcore.forward import continuation
    model = ForwardModel(coarse)
    params, posture = Parameters(), Posture("bent45", 45.0)
    assert params.smoothing >= model.options.smoothing_start
    cold = model.solve(params, posture)
    attempt = continuation._direct_attempt

    def failing(*args):
        problem, result, t, x = attempt(*args)
        return problem, dataclasses.replace(result, success=False, message="iteration limit"), t, x
    monkeypatch.setattr(continuation, "_direct_attempt", failing)
    fallback = model.solve(params, posture, start=cold.position)
    assert fallback.continuation_steps == 1 + cold.continuation_steps
    assert fallback.gradient_norm <= fallback.tolerance
    assert np.array_equal(fallback.position, cold.position)
