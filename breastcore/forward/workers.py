"""Forked worker processes that outlive a call: :class:`Workers`.

:func:`~breastcore.forward.parallel.fork_map` forks new workers at every call. An
identification solves its postures some ten times, and a freshly forked worker pays, at
each call, for the memory its solves touch for the first time: on ultra-thin 2,000-8,000
page faults a posture solve, 10-45 % of its time (``docs/benchmarks.md``), besides the
fork. A :class:`Workers` forks once, at its first call, and its workers keep their copy
of the target object (a measurement model, with its forward model's PARDISO handles,
factors and caches) from one call to the next, as a serial run keeps its own.
"""

from __future__ import annotations

import functools
import logging
import multiprocessing as mp
import os
import weakref
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from breastcore.forward.parallel import can_fork, fork_context, run_in_worker, start_worker

log = logging.getLogger(__name__)


class Workers:
    """``processes`` forked workers that call methods of ``target``, started at the first :meth:`map`.

    Parameters
    ----------
    target : object
        Its copy in each worker, as it was when the workers were forked, runs the tasks:
        what the target changes in a worker stays there, and what the caller changes later
        does not reach the workers. Tasks and results cross the process boundary by pickling.
    processes : int
    after_fork : callable, optional
        Runs once in each worker, before its first task.

    Notes
    -----
    Serial (the target's methods called here) where :func:`~breastcore.forward.parallel.can_fork`
    says no, and in a process that multiprocessing started (e.g. a ``fork_map`` worker running
    a sensitivity's re-identifications): multiprocessing's exit of such a process joins its
    children before anything shuts these workers down, and it hung in a test; on two cores nested
    workers only compete for the cores anyway. If a worker dies (killed, or a crash in native
    code), during a call or between calls, :meth:`map` forks new workers and runs the call again,
    once: a task that kills its worker again raises ``BrokenProcessPool``, and the next call forks
    new workers. The tasks must therefore be safe to repeat (the solves are). The workers are
    shut down by :meth:`close`, when this object is garbage-collected (the pool holds the target
    weakly, so a target that holds this object is collected too), or at exit.
    """

    def __init__(self, target, processes, after_fork=None):
        self.target, self.processes, self.after_fork = target, int(processes), after_fork
        self._pool, self._pid, self._finalizer = None, None, None

    def map(self, method, arguments):
        """``[getattr(target, method)(*args) for args in arguments]``, in the workers; results in order."""
        arguments = list(arguments)
        if not can_fork(min(self.processes, len(arguments))) or mp.parent_process() is not None:
            return [getattr(self.target, method)(*args) for args in arguments]
        tasks = [(method, args) for args in arguments]
        for attempt in range(2):
            try:
                return list(self._executor().map(run_in_worker, tasks))
            except BrokenProcessPool:
                self.close()
                if attempt:
                    raise
                log.warning("a worker process died; forking new workers and running the call again")

    @property
    def started(self) -> bool:
        """Whether this process has live workers."""
        return self._pool is not None and self._pid == os.getpid()

    def close(self):
        """Shut the workers down (a later :meth:`map` forks new ones); a no-op without workers."""
        if self.started:
            self._finalizer()
        self._pool = self._pid = self._finalizer = None

    def _executor(self):
        if not self.started:                       # none yet, or inherited from the process that forked this one
            # the pool keeps its initargs: a strong reference there would keep the target, and so this
            # object and its finalizer's pool, alive for ever (the finalizer registry holds the pool)
            self._pool = ProcessPoolExecutor(self.processes, mp_context=fork_context(), initializer=_start,
                                             initargs=(weakref.ref(self.target), self.after_fork))
            self._pid = os.getpid()
            self._finalizer = weakref.finalize(self, self._pool.shutdown, wait=True, cancel_futures=True)
        return self._pool


def _start(target_ref, after_fork):
    # alive here: a worker is forked, with fork, from within the call that submitted its first task,
    # and that call's frames, copied into this process, still hold the target
    start_worker(functools.partial(_call_method, target_ref()), after_fork)


def _call_method(target, task):
    method, args = task
    return getattr(target, method)(*args)
