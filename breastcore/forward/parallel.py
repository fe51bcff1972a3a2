"""``fork_map``: ``[function(i) for i in range(count)]`` in forked worker processes.

The function may be a closure over unpicklable state (a forward model with its
PARDISO handles): the forked children inherit it, and only the indices and the
results cross the process boundary.
"""

from __future__ import annotations

import multiprocessing as mp
from concurrent.futures import ProcessPoolExecutor

from breastcore.linalg.pardiso import one_thread_in_forked_worker

_CHILD_FUNCTION = None    # set in a forked worker only (by start_worker), never in the caller


def fork_map(function, count, processes=1, after_fork=None):
    """``[function(i) for i in range(count)]``, in up to ``processes`` forked processes.

    Serial where ``fork`` is not available, in a daemon process, or for
    ``processes ≤ 1``. The results are in index order; ``function`` must return
    picklable values and must not depend on what earlier calls did to shared state
    if the results are to be the same for every ``processes``. ``after_fork`` runs
    once in each child before its first call. An exception in ``function`` is
    raised here; a child that dies (a crash in native code) raises
    ``concurrent.futures.process.BrokenProcessPool`` instead of hanging.
    """
    processes = min(int(processes), count)
    if not can_fork(processes):
        return [function(i) for i in range(count)]
    # with fork, initargs reach the child through its copied memory, not pickling
    with ProcessPoolExecutor(processes, mp_context=fork_context(), initializer=start_worker,
                             initargs=(function, after_fork)) as pool:
        return list(pool.map(run_in_worker, range(count)))


def can_fork(processes) -> bool:
    """Whether work for ``processes`` workers goes to forked processes: more than one, ``fork``
    available, and this process not a daemon (which may not have children)."""
    return int(processes) > 1 and "fork" in mp.get_all_start_methods() and not mp.current_process().daemon


def fork_context():
    """The ``fork`` start method's context: the workers inherit their target through copied memory."""
    return mp.get_context("fork")


def start_worker(function, after_fork):
    """A forked worker's initializer: keep ``function`` (reached through copied memory) for
    :func:`run_in_worker`, put PARDISO on one thread (a multi-threaded one hangs or crashes
    after ``fork``: :func:`~breastcore.linalg.pardiso.one_thread_in_forked_worker`), then run
    ``after_fork``."""
    global _CHILD_FUNCTION
    _CHILD_FUNCTION = function
    one_thread_in_forked_worker()
    if after_fork is not None:
        after_fork()


def run_in_worker(argument):
    """``function(argument)`` in a worker that :func:`start_worker` set up."""
    return _CHILD_FUNCTION(argument)
