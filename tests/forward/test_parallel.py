"""fork_map: order, closures over unpicklable state, errors and dead children."""

import subprocess
import sys
import textwrap

import pytest

from breastcore.forward.parallel import fork_map


def test_fork_map_keeps_order_and_closes_over_unpicklable_state():
    state = {"lock": __import__("threading").Lock(), "offset": 10}   # a Lock cannot be pickled
    serial = fork_map(lambda i: (i + state["offset"], i * i), 7, processes=1)
    forked = fork_map(lambda i: (i + state["offset"], i * i), 7, processes=2)
    assert forked == serial == [(i + 10, i * i) for i in range(7)]


def test_fork_map_raises_the_error_of_a_call():
    def fails_at_three(i):
        if i == 3:
            raise ValueError("three")
        return i

    with pytest.raises(ValueError, match="three"):
        fork_map(fails_at_three, 5, processes=2)


def test_fork_map_raises_broken_pool_when_a_child_dies():
    """A child killed in native code must raise, not hang.

    Run in a fresh interpreter: forked children of a pytest-xdist worker inherit
    its execnet channel and threads, and once (CI, 2026-11-21) the worker itself
    went down while its pool was being torn down. The property under test is
    fork_map's, not xdist's.
    """
    script = textwrap.dedent("""
        import os
        from concurrent.futures.process import BrokenProcessPool
        from breastcore.forward.parallel import fork_map
        try:
            fork_map(lambda i: os._exit(1) if i == 1 else i, 3, processes=2)
        except BrokenProcessPool:
            print("broken")
        else:
            print("no error")
        print(fork_map(lambda i: i * i, 4, processes=2))   # the next pool still works
    """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split("\n")[:2] == ["broken", "[0, 1, 4, 9]"]
