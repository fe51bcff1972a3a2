"""breastcore/studies/paper_scene_logs.py reads the log lines the solver really writes."""

import logging
import time

import numpy as np

import pytest

from breastcore.forward.model import ForwardModel
from breastcore.forward.options import SolverOptions
from breastcore.forward.records import SolveError
from breastcore.inverse.identify import identify
from breastcore.inverse.operator import MeasurementModel
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import Posture, paper_postures
from breastcore.pipeline.logs import log_to
from breastcore.studies.paper_scene_logs import job_phases, solve_kinds


def test_solve_kinds_counts_cold_warm_and_final_step_failures(tmp_path):
    mesh = mesh_level("coarse")
    posture = Posture("bent45", 45.0)
    log = tmp_path / "identify.log"
    with log_to(log):
        model = ForwardModel(mesh)
        cold = model.solve(Parameters(), posture)
        warm = model.solve(Parameters(mu_breast=1.01 * Parameters().mu_breast), posture, cold.position)
        with pytest.raises(SolveError) as info:              # rtol below round-off: the final δ step fails
            ForwardModel(mesh, SolverOptions(rtol=1e-20, max_final_attempts=2, smoothing_start=1e-4)
                         ).solve(Parameters(), posture)
        # identify logs a failed trial solve in this form
        logging.getLogger("breastcore.inverse.identify").info("identify: step rejected, forward solve failed (%s)", info.value)
    iterations, counts, outcomes, retry = solve_kinds(log)
    assert counts == {"cold": 1, "warm": 1}
    assert iterations == {"cold": cold.iterations, "warm": warm.iterations}
    # without a δ phase a cold solve can take one continuation step, as a warm one does:
    # only the logged start kind tells them apart
    assert warm.continuation_steps == 1 and cold.continuation_steps == 1
    assert outcomes == {("converged", 0): 2, ("gave up", 2): 1}
    assert retry == {}                                          # 2 failures, not more than the cap of 3
    # against a cap of 1: timed from the first failure to the give-up, and to itself
    retry = solve_kinds(log, cap=1)[3]
    assert retry["after first"] > 0 and retry["up to cap"] == 0
    assert solve_kinds(log, cap=2)[3] == {}                    # not more failures than the cap


def test_solve_kinds_reads_logs_written_before_the_start_kind(tmp_path):
    """Older logs do not say the start kind; every solve then had a δ phase, so one continuation
    step was a warm solve, a first step at t ≤ 1 a cold one, and a first step at t > 1 a fallback."""
    prefix = "2026-11-30 10:00:00,000 DEBUG breastcore.forward.continuation: "
    lines = [prefix + "standing: step t=0.5000 load=0.5 δ=1.000e-04: converged in 9 iterations",
             prefix.replace("DEBUG", "INFO") + "standing: converged in 30 iterations (4 continuation steps), |g|=1e-9 N",
             prefix.replace("DEBUG", "INFO") + "fours: converged in 3 iterations (1 continuation steps), |g|=1e-9 N",
             prefix + "bent45: step t=1.5000 load=1 δ=1.000e-05: converged in 4 iterations",
             prefix.replace("DEBUG", "INFO") + "bent45: converged in 11 iterations (3 continuation steps), |g|=1e-9 N"]
    log = tmp_path / "old.log"
    log.write_text("\n".join(lines) + "\n")
    iterations, counts = solve_kinds(log)[:2]
    assert counts == {"cold": 1, "warm": 1, "warm fallback": 1}
    assert iterations == {"cold": 30, "warm": 3, "warm fallback": 11}


def test_job_phases_times_the_first_solve_and_what_lies_outside_the_log(tmp_path):
    mm = MeasurementModel(ForwardModel(mesh_level("coarse")), Parameters(), paper_postures())
    truth = np.array(Parameters().identified())
    target = mm.measure(mm.solve(truth))
    log = tmp_path / "identify.log"
    with log_to(log):
        tic = time.perf_counter()
        identify(mm, target, truth * 1.1)
        wall = time.perf_counter() - tic
    lines = log.read_text().splitlines()
    span = (_stamp(lines[-1]) - _stamp(lines[0])).total_seconds()
    first, outside = job_phases(log, wall + 2.0)               # as if the process took 2 s more to start
    assert 0 < first < span and any("identify it=0 " in line for line in lines)
    assert outside == pytest.approx(wall + 2.0 - span) and outside >= 2.0


def _stamp(line):
    import datetime
    return datetime.datetime.strptime(line[:23], "%Y-%m-%d %H:%M:%S,%f")


def test_modified_steps_count_the_projection_its_shift_and_the_inertia_shifts():
    from breastcore.studies.paper_scene_logs import MODIFIED
    modes = ["exact", "chord", "project", "shift", "shift0.01", "shift0.1", "exact"]
    log = "".join(f"2026-12-03 10:00:00,000 DEBUG breastcore.nonlinear.newton: newton it={i} |g|=1.0e-03 step=1 "
                  f"E=-4.1e-02 mode={mode} neg=0\n" for i, mode in enumerate(modes))
    assert len(MODIFIED.findall(log)) == 4
