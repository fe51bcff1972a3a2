"""Identification: implicit Jacobian vs central differences, inverse-crime recovery,
the paper's Gauss-Newton, rejected failed solves, and the output dataset."""

import dataclasses
import gc
import multiprocessing as mp
import re

import numpy as np
import pytest
from linear_model import LinearModel  # tests/linear_model.py

from breastcore.cli.main import main
from breastcore.forward.model import ForwardModel
from breastcore.forward.records import SolveError
from breastcore.inverse.identify import identify
from breastcore.inverse.transforms import from_unconstrained, to_unconstrained, unconstrained_chain
from breastcore.inverse.operator import MeasurementModel
from breastcore.inverse.options import IdentificationOptions
from breastcore.io.datasets import open_dataset
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures

TRUTH = np.array(Parameters().identified())


@pytest.fixture(scope="module")
def problem():
    mm = MeasurementModel(ForwardModel(mesh_level("coarse")), Parameters(), paper_postures())
    solutions = mm.solve(TRUTH)
    return mm, solutions, mm.measure(solutions)


# c = 100 Pa: the back slides; the default c: most of it sticks (|u| ≲ δ), where the smoothed
# Chassaignac gradient bends on the length δ (the R, H steps of the implicit Jacobian once missed
# that by 1e-4); 5000 Pa: all of it sticks
@pytest.mark.parametrize("chassaignac", [100.0, Parameters().chassaignac, 5000.0])
def test_implicit_jacobian_matches_central_differences(problem, chassaignac):
    mm, solutions, target = problem
    if chassaignac != mm.base.chassaignac:
        mm = MeasurementModel(mm.model, mm.base.replace(chassaignac=chassaignac), mm.postures)
        solutions = mm.solve(TRUTH)
        target = mm.measure(solutions)
    implicit = mm.implicit_jacobian(TRUTH, solutions) * TRUTH / target[..., None]
    central = mm.fd_jacobian(TRUTH, solutions, rel_step=1e-5, central=True) * TRUTH / target[..., None]
    assert np.abs(implicit - central).max() <= 1e-6 * np.abs(central).max()
    assert np.abs(central).max() > 0.1          # the Jacobian is not trivially small


def test_unconstrained_map_round_trips_and_its_chain_rule_is_exact():
    z = to_unconstrained(TRUTH)
    assert np.allclose(from_unconstrained(z), TRUTH, rtol=1e-14)
    h = 1e-6
    fd = np.column_stack([(from_unconstrained(z + h * e) - from_unconstrained(z - h * e)) / (2 * h) for e in np.eye(6)])
    assert np.allclose(unconstrained_chain(TRUTH), fd, rtol=1e-7, atol=1e-12)
    R, H = from_unconstrained([0.0, 30.0, 0, 0, 0, 0])[:2]
    assert 0 < H < R                              # the bound H < R holds by construction


def test_lm_recovers_truth_from_30_percent_off(problem):
    mm, _, target = problem
    start = TRUTH * np.array([1.3, 0.75, 0.7, 1.3, 1.25, 0.7])
    result = identify(mm, target, start)
    assert result.success
    assert np.abs(result.estimate / TRUTH - 1).max() <= 1e-4
    assert result.cost[-1] < 1e-12 < result.cost[0]
    assert len(result.parameters) == len(result.cost) == len(result.wall_time)
    # the estimate's shapes are those of the cold solve that defines M(Λ), not of another branch
    cold = mm.measure(mm.solve(result.estimate))
    assert np.abs(mm.measure(result.solutions) / cold - 1).max() <= 1e-6


@pytest.mark.parametrize("start", [
    [0.0595446, 0.0216535, 1304.22, 156.866, 6365.42, 2153.78],    # H 57 % low, λ 30 %, μ_s 35 % high
    [0.0550004, 0.0347331, 907.26, 166.11, 3435.11, 1933.04],      # λ_s 57 % low
])
def test_lm_recovers_truth_from_starts_up_to_60_percent_off(problem, start):
    """Two of the ±60 % starts on which LM with trf's own first radius (‖z₀‖ ≈ 15) failed."""
    mm, _, target = problem
    result = identify(mm, target, np.array(start))
    assert result.success, result.message
    assert np.abs(result.estimate / TRUTH - 1).max() <= 1e-4


def test_initial_trust_radius_bounds_the_first_step(problem):
    mm, _, target = problem
    start = TRUTH * np.array([1.6, 0.5, 1.6, 0.4, 0.4, 1.6])
    radius = 0.05
    result = identify(mm, target, start, IdentificationOptions(initial_trust_radius=radius, max_iterations=1))
    first = result.parameters[1] if len(result.parameters) > 1 else result.parameters[0]
    step = to_unconstrained(first) - to_unconstrained(start)
    assert 0 < np.linalg.norm(step) <= radius * (1 + 1e-9)


@pytest.mark.parametrize("method", ["lm", "gauss-newton"])
def test_max_iterations_caps_accepted_steps(problem, method):
    """The paper reports its losses "after 25 iterations": the cap counts accepted steps."""
    mm, _, target = problem
    opts = IdentificationOptions(method=method, jacobian="fd" if method == "gauss-newton" else "implicit",
                                 max_iterations=3)
    result = identify(mm, target, TRUTH * np.array([1.3, 0.8, 1.3, 0.7, 1.3, 0.7]), opts)
    assert result.iterations == 3 and not result.success
    assert result.message == "iteration limit (3)"
    assert len(result.cost) - 1 == 3                   # no branch restart after a run that stopped at its cap
    assert result.cost[-1] < result.cost[0]


def test_paper_gauss_newton_decreases_the_cost(problem):
    mm, _, target = problem
    start = TRUTH * 1.1
    opts = IdentificationOptions(method="gauss-newton", jacobian="fd", fd_step=1e-4, max_iterations=8)
    result = identify(mm, target, start, opts)
    assert result.cost[-1] < 1e-3 * result.cost[0]


def test_failed_forward_solve_is_rejected_not_fatal(problem, monkeypatch):
    mm, _, target = problem
    model = mm.model
    real = model.solve
    calls = {"n": 0}

    def flaky(params, posture, start=None):
        calls["n"] += 1
        if calls["n"] in (4, 5):                   # the first trial step fails
            raise SolveError("injected", iterations=1, gradient_norm=1.0, tolerance=0.1, min_det_F=0.5,
                             load_factor=1.0, smoothing=1e-6, posture=posture.name)
        return real(params, posture, start)

    monkeypatch.setattr(model, "solve", flaky)
    result = identify(mm, target, TRUTH * 1.2)
    assert result.failed_solves >= 1
    assert result.success and np.abs(result.estimate / TRUTH - 1).max() <= 1e-4


class _FailsAwayFromTheStart(LinearModel):
    """Every solve away from the start fails, as a forward solve does far outside the model's range."""

    start = None

    def solve(self, values, warm=None, jacobian=False):
        self.start = np.array(values, float) if self.start is None else self.start
        if not np.array_equal(values, self.start):
            self.solves += 1
            raise SolveError("injected", iterations=1, gradient_norm=1.0, tolerance=0.1, min_det_F=0.5,
                             load_factor=1.0, smoothing=1e-6, posture="standing")
        return super().solve(values, warm, jacobian)


@pytest.mark.parametrize("scale", [1.0, 1e-6])
def test_a_failed_solve_is_never_an_accepted_step_however_badly_the_start_fits(scale):
    """Measurements entered a million times too small (a patient file in SI units read as ml and mm)
    give relative residuals of 1e6: the fixed residual of a failed solve (1e3) was then lower, scipy
    accepted the failed point, and asked for a Jacobian there (KeyError, no dataset)."""
    mm = _FailsAwayFromTheStart()
    target = LinearModel().measure(LinearModel().solve(TRUTH)) * scale
    start = TRUTH * 1.2
    result = identify(mm, target, start)
    assert result.failed_solves >= 1 and np.array_equal(result.estimate, start)
    assert all(np.array_equal(p, start) for p in result.parameters)


def test_a_start_that_is_not_positive_is_refused_before_any_solve():
    mm = LinearModel()
    with pytest.raises(ValueError, match="must be > 0"):
        identify(mm, mm.measure(mm.solve(TRUTH)), TRUTH * np.array([1, 1, 0, 1, 1, 1]))
    assert mm.solves == 1


def test_identify_command_writes_history_estimate_and_uncertainty(tmp_path):
    sol, meas, out = tmp_path / "s.nc", tmp_path / "m.nc", tmp_path / "id.nc"
    assert main(["solve", "--mesh", "coarse", "--out", str(sol)]) == 0
    assert main(["measure", str(sol), "--out", str(meas)]) == 0
    assert main(["identify", "--measurements", str(meas), "--mesh", "coarse", "--processes", "2",
                 "--initial", "R=0.06,mu_breast=120", "--out", str(out)]) == 0
    assert main(["identify", "--measurements", str(meas), "--mesh", "coarse", "--processes", "0",
                 "--out", str(tmp_path / "never.nc")]) == 2
    assert not (tmp_path / "never.nc").exists()
    assert main(["sensitivity", str(out), "--processes", "0", "--out", str(tmp_path / "never.nc")]) == 2
    ds = open_dataset(out)
    for name in ("parameters", "cost", "measurement_error", "wall_time", "estimate", "jacobian", "covariance",
                 "interval_low", "interval_high", "singular_values", "position"):
        assert name in ds and "units" in ds[name].attrs and "long_name" in ds[name].attrs
    assert ds["cost"].dims == ("iteration",) and ds["measurement_error"].dims == ("iteration", "posture", "quantity")
    ok = ds["determined"].values.astype(bool)
    assert ok.any() and np.all(ds["interval_low"].values[ok] < ds["estimate"].values[ok])
    assert np.all(ds["estimate"].values[ok] < ds["interval_high"].values[ok])
    assert np.all(np.isnan(ds["interval_low"].values[~ok])) and np.all(ds["interval_decades"].values[~ok] > 1)
    assert np.abs(ds["relative_error"]).max() < 1e-4
    # not converging: non-zero exit, history kept
    bad = tmp_path / "bad.nc"
    assert main(["identify", "--measurements", str(meas), "--mesh", "coarse", "--initial", "R=0.07",
                 "--method", "gauss-newton", "--jacobian", "fd", "--max-iterations", "1", "--out", str(bad)]) == 1
    assert open_dataset(bad).sizes["iteration"] == 2


def test_cold_solves_in_two_processes_equal_serial_ones_bit_for_bit(problem):
    mm, solutions, _ = problem
    parallel = MeasurementModel(mm.model, Parameters(), paper_postures(), processes=2)
    values = TRUTH * 1.02
    serial = MeasurementModel(mm.model, Parameters(), paper_postures()).solve(values)
    forked = parallel.solve(values)
    assert parallel.solves == 3
    for name, solution in serial.items():
        assert np.array_equal(forked[name].position, solution.position)
    with pytest.raises(ValueError, match="processes"):
        MeasurementModel(mm.model, Parameters(), paper_postures(), processes=0)


def test_an_identification_in_two_processes_equals_the_serial_one_bit_for_bit(problem):
    mm, _, target = problem
    start = TRUTH * np.array([1.2, 0.8, 1.2, 0.8, 1.2, 0.8])
    options = IdentificationOptions(max_iterations=3)
    serial = identify(MeasurementModel(mm.model, Parameters(), paper_postures()), target, start, options)
    fresh = ForwardModel(mesh_level("coarse"))                # as a user starts: nothing solved in the parent
    with MeasurementModel(fresh, Parameters(), paper_postures(), processes=2) as parallel:
        forked = identify(parallel, target, start, options)
        assert parallel._workers.started                    # the same workers served every evaluation
    assert not parallel._workers.started                    # closed on leaving the with block
    assert np.array_equal(np.array(forked.parameters), np.array(serial.parameters))
    assert np.array_equal(forked.cost, serial.cost) and forked.forward_solves == serial.forward_solves
    assert np.array_equal(forked.jacobian, serial.jacobian)


def test_a_failed_posture_in_a_worker_raises_its_solve_error(problem, monkeypatch):
    mm, _, _ = problem
    solve = ForwardModel.solve

    def fours_fails(self, params, posture, start=None):
        if posture.name == "fours":
            raise SolveError("continuation stalled", iterations=1, gradient_norm=1.0, tolerance=1e-9,
                             min_det_F=0.5, load_factor=1.0, smoothing=1e-6, posture="fours")
        return solve(self, params, posture, start)
    monkeypatch.setattr(ForwardModel, "solve", fours_fails)          # before the workers are forked
    with MeasurementModel(mm.model, Parameters(), paper_postures(), processes=2) as parallel:
        with pytest.raises(SolveError, match="fours") as raised:
            parallel.solve(TRUTH)
        assert parallel._workers.started                    # raised by a worker, whose pool lives on
        assert raised.value.posture == "fours" and raised.value.iterations == 1     # its diagnostics, unpickled


def test_a_model_in_two_processes_is_collected_and_its_workers_shut_down(problem):
    mm, _, _ = problem
    before = {p.pid for p in mp.active_children()}
    parallel = MeasurementModel(mm.model, Parameters(), paper_postures(), processes=2)
    parallel.solve(TRUTH)
    ours = {p.pid for p in mp.active_children()} - before
    assert ours
    del parallel                                              # not closed
    gc.collect()
    assert not ours & {p.pid for p in mp.active_children()}


def test_jacobian_rows_from_the_workers_equal_the_serial_jacobian(problem, monkeypatch):
    mm, _, _ = problem
    values = TRUTH * 1.02
    parallel = MeasurementModel(mm.model, Parameters(), paper_postures(), processes=2)
    solutions = parallel.solve(values, jacobian=True)
    serial_tangents, parallel_tangents = {}, {}
    serial = MeasurementModel(mm.model, Parameters(), paper_postures()).implicit_jacobian(values, solutions | {
        name: dataclasses.replace(s, jacobian_rows=None) for name, s in solutions.items()},   # no cached rows
        tangents=serial_tangents)
    monkeypatch.setattr(MeasurementModel, "_posture_jacobian", lambda *a, **k: pytest.fail("not reused"))
    np.testing.assert_allclose(parallel.implicit_jacobian(values, solutions, tangents=parallel_tangents), serial,
                               rtol=1e-12, atol=0)
    assert parallel_tangents.keys() == serial_tangents.keys() == {p.name for p in paper_postures()}
    for name, tangent in serial_tangents.items():             # the workers' ∂x/∂Λ, for the tangent starts
        np.testing.assert_allclose(parallel_tangents[name], tangent, rtol=0, atol=1e-12 * np.abs(tangent).max())
    with pytest.raises(pytest.fail.Exception):                  # rows at other Λ are not reused
        parallel.implicit_jacobian(values * 1.01, solutions)


@pytest.mark.parametrize("drift, restarts", [(1e-3, 0), (5e-2, 2)])
def test_a_branch_drift_below_the_fit_residual_is_not_chased(drift, restarts):
    """Data 1 % off the model (RMS residual ≈ 9e-3): a 1e-3 drift is kept, a 5e-2 drift is chased."""
    mm = LinearModel(drift)
    noise = 0.01 * np.where(np.arange(15) % 2 == 0, 1.0, -1.0)
    target = (mm.measure(mm.solve(TRUTH, mm.warm_starts())).ravel() * (1 + noise)).reshape(3, 5)
    result = identify(mm, target, TRUTH * 1.2)
    assert result.success
    assert 1e-3 < np.sqrt(result.cost[-1] / 15) < 5e-2
    assert result.branch_restarts == restarts
    assert result.branch_drift == pytest.approx(drift / (1 + drift), rel=1e-6)


@pytest.mark.parametrize("method", ["lm", "gauss-newton"])
@pytest.mark.parametrize("drift", [0.0, 5e-2])
def test_iteration_cap_spans_restarts_and_success_means_converged(method, drift):
    """For every cap: at most that many iterations over all runs; success iff a convergence test was met.

    Includes a run that converges exactly at its cap (success, although stopped by the cap)
    and Gauss–Newton restarts that end at the cap (failure, although the first run had converged).
    """
    noise = 0.01 * np.where(np.arange(15) % 2 == 0, 1.0, -1.0)
    mm = LinearModel(drift)
    target = (mm.measure(mm.solve(TRUTH, mm.warm_starts())).ravel() * (1 + noise)).reshape(3, 5)
    free = identify(mm, target, TRUTH * 1.2, IdentificationOptions(method=method))
    assert free.success
    for cap in range(1, free.iterations + 2):
        result = identify(LinearModel(drift), target, TRUTH * 1.2,
                          IdentificationOptions(method=method, max_iterations=cap))
        assert result.iterations <= cap
        assert result.success == (not result.message.startswith("iteration limit")), (cap, result.message)
        if cap >= free.iterations and drift == 0:
            assert result.success, (cap, result.message)


class _SpoiledSecondStep(LinearModel):
    """The second Gauss–Newton trial point reads every measurement 30 % high: the cost rises there."""

    def solve(self, values, warm=None, jacobian=False):
        solutions = super().solve(values, warm, jacobian)
        solutions["spoiled"] = self.solves == 3          # 1: initial solve, 2: first step, 3: second step
        return solutions

    def measure(self, solutions):
        return super().measure(solutions) * (1.3 if solutions.get("spoiled") else 1.0)


def test_gauss_newton_returns_its_best_iterate_when_the_cost_rises_and_says_so():
    """It kept the worse trial point as its estimate, and its message read 2·new − old → new."""
    mm = _SpoiledSecondStep()
    target = mm.measure(mm.solve(TRUTH))
    mm.solves = 0
    opts = IdentificationOptions(method="gauss-newton", jacobian="implicit", max_iterations=10)
    result = identify(mm, target, TRUTH * 1.2, opts)
    assert result.iterations == 1 and not result.success and len(result.cost) == 2
    assert np.array_equal(result.estimate, result.parameters[1]) and result.cost[1] == min(result.cost)
    numbers = re.search(r"raised the cost \((\S+) → (\S+)\)", result.message)
    assert numbers, result.message
    before, after = float(numbers.group(1)), float(numbers.group(2))
    assert before == pytest.approx(result.cost[1], rel=1e-3) and after > before
    assert "best iterate (iteration 1)" in result.message


def test_fixed_iterations_runs_them_all_and_claims_no_convergence():
    mm = _SpoiledSecondStep()
    target = mm.measure(mm.solve(TRUTH))
    mm.solves = 0
    opts = IdentificationOptions(method="gauss-newton", jacobian="implicit", max_iterations=7, fixed_iterations=True)
    result = identify(mm, target, TRUTH * 1.2, opts)
    assert result.iterations == 7 == len(result.cost) - 1 - result.branch_restarts
    assert not result.success and "fixed iteration count (7)" in result.message
    assert result.cost[-1] < 1e-12 < result.cost[2]            # it went on past the rise and converged anyway
    with pytest.raises(ValueError, match="'gauss-newton' only"):
        IdentificationOptions(fixed_iterations=True)


@pytest.mark.parametrize("method", ["lm", "gauss-newton"])
def test_cost_rtol_stops_the_same_run_at_its_first_small_relative_decrease(method):
    """With cost_rtol the history is the prefix, bit for bit, of the run without it, cut after
    the first accepted step with E(Λⁿ) − E(Λⁿ⁺¹) < cost_rtol · E(Λⁿ); the stop counts as converged.
    Data 2 % off the model, so that the cost levels off above zero."""
    def fresh():        # no warm state carried over between the two runs
        return MeasurementModel(ForwardModel(mesh_level("coarse")), Parameters(), paper_postures())

    mm = fresh()
    target = mm.measure(mm.solve(TRUTH)) * (1 + 0.02 * np.where(np.arange(15) % 2 == 0, 1.0, -1.0).reshape(3, 5))
    start = TRUTH * np.array([1.2, 0.9, 1.2, 0.8, 1.2, 0.8])
    jacobian = "fd" if method == "gauss-newton" else "implicit"
    full = identify(fresh(), target, start, IdentificationOptions(method=method, jacobian=jacobian, max_iterations=12))
    cost = np.array(full.cost)
    relative_decrease = (cost[:-1] - cost[1:]) / cost[:-1]
    cost_rtol = 0.05
    small = np.flatnonzero(relative_decrease < cost_rtol)
    assert small.size and small[0] + 1 < full.iterations      # the test fires before the full run ends
    stop = small[0] + 1                                       # iterations done when it fires
    cut = identify(fresh(), target, start, IdentificationOptions(method=method, jacobian=jacobian,
                                                                 max_iterations=12, cost_rtol=cost_rtol))
    assert cut.success and "below cost_rtol = 0.05" in cut.message
    assert cut.iterations == stop
    np.testing.assert_array_equal(np.array(cut.parameters)[:stop + 1], np.array(full.parameters)[:stop + 1])
    np.testing.assert_array_equal(cut.cost[:stop + 1], full.cost[:stop + 1])


@pytest.mark.parametrize("value", [-0.1, 1.0, 2.0])
def test_cost_rtol_outside_0_1_is_refused(value):
    with pytest.raises(ValueError, match="cost_rtol must be in"):
        IdentificationOptions(cost_rtol=value)


def test_solutions_record_whether_they_were_solved_cold_and_cold_solves_repeat_bit_for_bit(problem):
    """The premise of skipping the branch check: a cold solve at the same Λ repeats, after other solves."""
    mm = MeasurementModel(problem[0].model, Parameters(), paper_postures())
    warm = mm.warm_starts()
    far = mm.solve(TRUTH * 1.3, warm)                            # nothing remembered: cold
    assert mm.solved_cold(far)
    warm.remember(far, TRUTH * 1.3)
    near = mm.solve(TRUTH * 1.31, warm)                          # within warm_radius: warm
    assert not mm.solved_cold(near)
    again = mm.solve(TRUTH * 1.3)                                # no warm starts: cold
    assert mm.solved_cold(again)
    for name, solution in far.items():
        assert np.array_equal(again[name].position, solution.position)


def test_m_of_lambda_does_not_depend_on_call_history(problem):
    """M(Λ) keeps no state: a solve leaves the warm starts it was given as they were, and
    the same call gives the same equilibria after other solves (it remembered each call's
    equilibria, and a caller such as scipy's Jacobian callback steered that from outside)."""
    mm = MeasurementModel(problem[0].model, Parameters(), paper_postures())
    warm = mm.warm_starts()
    first = mm.solve(TRUTH * 1.02, warm)
    assert warm.values is None and warm.positions == {}           # not changed by the solve
    mm.solve(TRUTH * 0.97)
    mm.solve(TRUTH * 1.01, mm.warm_starts())
    second = mm.solve(TRUTH * 1.02, warm)
    for name, solution in first.items():
        assert np.array_equal(second[name].position, solution.position)


def test_branch_check_is_skipped_when_the_estimate_was_solved_cold(monkeypatch):
    """Cold estimate equilibria: no cold re-solve and drift 0; warm ones are still checked."""
    from breastcore.inverse.branch import check_branch
    from breastcore.inverse.history import IdentificationRun
    mm = LinearModel(5e-2)
    calls = []
    solve = mm.solve
    monkeypatch.setattr(mm, "solve", lambda values, warm=None, jacobian=False:
                        calls.append(warm is None) or solve(values, warm, jacobian))
    target = mm.measure(solve(TRUTH, mm.warm_starts()))
    for cold, expected_calls in ((True, []), (False, [True])):
        calls.clear()
        run = IdentificationRun(mm, target, np.ones_like(target))
        run.success = True
        run.parameters.append(TRUTH.copy())
        run.cost.append(1.0)
        warm = mm.warm_starts()
        run.solutions = solve(TRUTH, None if cold else warm)
        check_branch(mm, target, np.ones_like(target), IdentificationOptions(), run, lambda *a: None, warm)
        assert calls == expected_calls
        assert (run.branch_drift == 0.0) == cold


def test_fewer_weighted_measurements_than_parameters_is_refused_before_any_solve():
    mm = LinearModel()
    target = mm.measure(mm.solve(TRUTH))
    mm.solves = 0
    one_posture = np.zeros_like(target)
    one_posture[0] = 1.0                                    # five measurements for six parameters
    with pytest.raises(ValueError, match="only 5 of 15 measurements have weight > 0: 5 measurements cannot "
                                         "determine 6 parameters; give weight > 0") as err:
        identify(mm, target, TRUTH * 1.1, IdentificationOptions(), weights=one_posture)
    assert "two postures" not in str(err.value)                # three were measured
    with pytest.raises(ValueError, match="every weight is 0"):
        identify(mm, target, TRUTH * 1.1, IdentificationOptions(), weights=np.zeros_like(target))
    with pytest.raises(ValueError, match="measure at least two postures"):
        identify(mm, target[:1], TRUTH * 1.1, IdentificationOptions())
    assert mm.solves == 0
    one_posture[1, 0] = 1.0                                 # six: determined, and it runs
    assert identify(mm, target, TRUTH * 1.1, IdentificationOptions(max_iterations=3), weights=one_posture).cost


def test_lm_solves_the_start_once_and_takes_no_jacobian_twice_at_the_same_point(problem, monkeypatch):
    """The start's equilibria are the first solve's (LM's evaluation at d = 0 is not re-solved),
    and the final Jacobian is LM's at its last accepted point, not recomputed; it equals a fresh
    one bit for bit."""
    mm, _, target = problem
    mm = MeasurementModel(mm.model, mm.base, mm.postures)
    solved, jacobians = [], []
    solve, jacobian = mm.solve, mm.implicit_jacobian
    monkeypatch.setattr(mm, "solve", lambda values, *a, **k: solved.append(np.array(values)) or solve(values, *a, **k))
    monkeypatch.setattr(mm, "implicit_jacobian",
                        lambda values, *a, **k: jacobians.append(np.array(values)) or jacobian(values, *a, **k))
    start = TRUTH * np.array([1.3, 0.75, 0.7, 1.3, 1.25, 0.7])
    result = identify(mm, target, start)
    assert result.success
    assert sum(np.allclose(v, start, rtol=1e-12, atol=0) for v in solved) == 1
    assert len(jacobians) == len({tuple(v) for v in jacobians}) >= 2
    fresh = jacobian(result.estimate, result.solutions) * result.estimate / target[..., None]
    np.testing.assert_array_equal(result.jacobian, fresh)


def test_jacobian_steps_stay_inside_0_lt_H_lt_R(problem):
    """A forward step H(1 + ε) ≥ R built an inadmissible cap (ParameterError, no dataset): with
    ``--fd-step 0.2`` at the paper's H/R = 0.89, and in the implicit Jacobian's central R, H steps
    once LM had driven H/R to 1 − 1e-8. The FD column is now the backward difference; the implicit
    one's step is at most half of R − H."""
    mm, solutions, _ = problem
    step = 0.2
    assert TRUTH[1] * (1 + step) >= TRUTH[0]
    J = mm.fd_jacobian(TRUTH, solutions, rel_step=step)
    below = TRUTH.copy()
    below[1] *= 1 - step
    backward = (mm.measure(solutions) - mm.measure(mm.solve(below, mm.warm_starts()))) / (step * TRUTH[1])
    np.testing.assert_allclose(J[..., 1], backward, rtol=1e-6)
    near = TRUTH.copy()
    near[1] = near[0] * (1 - 1e-8)
    flat = mm.solve(near)
    rows = mm.implicit_jacobian(near, flat)
    assert np.all(np.isfinite(rows)) and np.abs(rows[..., 0]).max() > 0
