"""Run a Python script in a fresh interpreter, in a session of its own, with a time limit."""

import os
import signal
import subprocess
import sys


def run_script(script, env=None, timeout=60.0):
    """``(return code, stdout, stderr)`` of ``python -c script``; on a timeout the whole process group
    (forked workers included, which may hang) is killed and ``TimeoutExpired`` raised."""
    with subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          env=env, start_new_session=True) as child:
        try:
            out, err = child.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(child.pid, signal.SIGKILL)
            raise
    return child.returncode, out, err
