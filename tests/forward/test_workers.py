"""Workers: forked once, kept across calls, each with its own copy of the target; errors and dead workers."""

import gc
import multiprocessing as mp
import os
import subprocess
import sys
import textwrap

import pytest

from subprocesses import run_script

from breastcore.forward.workers import Workers
from breastcore.linalg import pardiso


class Counter:
    """A target whose calls show where they ran and what its copy remembers."""

    def __init__(self):
        self.calls = 0

    def where(self, value):
        self.calls += 1
        return os.getpid(), self.calls, value * value

    def fails(self, value):
        raise ValueError(f"bad value {value}")


def test_workers_are_forked_once_and_keep_their_copy_of_the_target_across_calls():
    target = Counter()
    workers = Workers(target, 2)
    assert not workers.started
    try:
        first = workers.map("where", [(i,) for i in range(6)])
        assert workers.started
        second = workers.map("where", [(i,) for i in range(6)])
        assert [r[2] for r in first] == [r[2] for r in second] == [i * i for i in range(6)]    # in order
        pids = {r[0] for r in first + second}
        assert os.getpid() not in pids and 1 <= len(pids) <= 2     # the same (at most two) workers both times
        for pid in pids:                                          # each copy counts its own calls, 1, 2, ...
            counts = [r[1] for r in first + second if r[0] == pid]
            assert counts == list(range(1, len(counts) + 1))
        assert target.calls == 0                                  # the caller's object is not the workers'
    finally:
        workers.close()
    assert not workers.started
    again = Workers(target, 2)
    try:
        assert {r[0] for r in again.map("where", [(1,), (2,)])}.isdisjoint(pids)   # new workers after close
    finally:
        again.close()


def test_one_process_runs_the_calls_here():
    target = Counter()
    workers = Workers(target, 1)
    assert workers.map("where", [(3,), (4,)]) == [(os.getpid(), 1, 9), (os.getpid(), 2, 16)]
    assert target.calls == 2 and not workers.started


def test_an_error_in_a_worker_is_raised_here_and_the_workers_stay_usable():
    workers = Workers(Counter(), 2)
    try:
        with pytest.raises(ValueError, match="bad value 2"):
            workers.map("fails", [(2,), (3,)])
        assert [r[2] for r in workers.map("where", [(5,), (6,)])] == [25, 36]
    finally:
        workers.close()


def test_a_task_that_kills_its_worker_twice_raises_broken_pool_and_the_next_call_forks_new_workers():
    """The call is run again once, on new workers, and its task kills one again. In a fresh interpreter,
    for the reason given in test_parallel's dead-child test."""
    script = textwrap.dedent("""
        import os
        from concurrent.futures.process import BrokenProcessPool
        from breastcore.forward.workers import Workers

        class Target:
            def square(self, i):
                if i == 1 and os.environ.get("DIE") == "1":
                    os._exit(1)
                return i * i

        os.environ["DIE"] = "1"
        workers = Workers(Target(), 2)
        try:
            workers.map("square", [(0,), (1,), (2,)])
        except BrokenProcessPool:
            print("broken", workers.started)
        os.environ["DIE"] = "0"                     # the new workers are forked with this environment
        print(workers.map("square", [(0,), (1,), (2,)]), workers.started)
        workers.close()
    """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split("\n")[:2] == ["broken False", "[0, 1, 4] True"]
    assert "forking new workers and running the call again" in run.stderr      # the call was run again first


def test_a_worker_killed_between_calls_is_replaced_and_the_next_call_succeeds():
    """Before, the call after a worker's death between calls raised BrokenProcessPool (its pool was broken)."""
    script = textwrap.dedent("""
        import os, signal, time
        from breastcore.forward.workers import Workers

        class Target:
            def where(self, i):
                time.sleep(0.05)                    # most likely one task a worker; either way the pool breaks
                return os.getpid(), i * i

        workers = Workers(Target(), 2)
        first = workers.map("where", [(0,), (1,)])
        pids = {pid for pid, _ in first}
        os.kill(min(pids), signal.SIGKILL)
        time.sleep(0.5)                             # the pool notices the death while idle
        second = workers.map("where", [(2,), (3,)])
        print([value for _, value in second], workers.started, {pid for pid, _ in second}.isdisjoint(pids))
        workers.close()
    """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split("\n")[0] == "[4, 9] True True"
    assert "forking new workers and running the call again" in run.stderr


def test_workers_in_a_fork_map_worker_run_serially_there_and_let_it_exit():
    """Workers forked inside a multiprocessing child hung it (found while writing these tests): there they run
    serially. In a fresh interpreter with a timeout, so that a hang fails instead of blocking the suite."""
    script = textwrap.dedent("""
        import os
        from breastcore.forward.parallel import fork_map
        from breastcore.forward.workers import Workers

        class Target:
            def pid(self, i):
                return os.getpid()

        left_open = []

        def job(i):
            workers = Workers(Target(), 2)
            left_open.append(workers)                 # never closed
            pids = set(workers.map("pid", [(0,), (1,), (2,)]))
            return pids == {os.getpid()} and not workers.started

        print(fork_map(job, 2, processes=2))
    """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[True, True]"


def test_a_target_that_holds_its_workers_is_collected_and_its_workers_shut_down():
    before = {p.pid for p in mp.active_children()}
    target = Counter()
    target.workers = Workers(target, 2)                     # the cycle a MeasurementModel makes
    target.workers.map("where", [(1,), (2,)])
    ours = {p.pid for p in mp.active_children()} - before
    assert ours                                             # the workers run
    del target
    gc.collect()
    assert not ours & {p.pid for p in mp.active_children()}   # collected, and its workers joined


@pytest.mark.skipif(not pardiso.available(), reason="PARDISO (MKL) not installed")
def test_postures_in_two_processes_on_a_two_thread_pardiso_match_one_process():
    """``BREASTCORE_PARDISO_THREADS=2``: the parent analyses on 2 threads, its forked workers factorise
    on 1 and redo the analyses. Before, a worker hung in its first factorisation (GNU OpenMP's threads
    are not copied by fork) or, on 1 thread, segfaulted (a handle analysed on 2). In a fresh
    interpreter, whose MKL has not been loaded yet."""
    script = textwrap.dedent("""
        import numpy as np
        from breastcore.forward.model import ForwardModel
        from breastcore.inverse.operator import MeasurementModel
        from breastcore.model.mesh import mesh_level
        from breastcore.model.parameters import Parameters
        from breastcore.model.postures import paper_postures

        model = ForwardModel(mesh_level("medium"))
        values = np.array(Parameters().identified())
        with MeasurementModel(model, Parameters(), paper_postures(), processes=2) as mm:
            parallel = mm.measure(mm.solve(values))
        with MeasurementModel(model, Parameters(), paper_postures()) as mm:
            serial = mm.measure(mm.solve(values))
        print(float(np.abs(parallel / serial - 1).max()))
    """)
    code, out, err = run_script(script, dict(os.environ, **{pardiso.PARDISO_THREADS_ENV: "2"}), timeout=60)
    assert code == 0, err
    # the solve tolerance's order: a 2-thread factor rounds differently from a 1-thread one
    assert float(out.split()[-1]) <= 1e-8
