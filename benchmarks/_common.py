"""Shared helpers of the benchmark scripts: timing medians, subprocess runs with a
time cap and peak memory, table printing, PASS/MISS verdicts and the machine line.

Every number a benchmark prints comes from these helpers, so that the tables in
``docs/benchmarks.md`` can be pasted from the output unchanged.
"""

from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import textwrap
import time
from pathlib import Path


from breastcore.report.text_table import fmt, header, machine_line, print_table  # noqa: F401 (re-exported)
from breastcore.studies.mesh_convergence import fit_exponent  # noqa: F401 (re-exported)

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def timed(fn, repeats: int):
    """Run ``fn()`` ``repeats`` times; return (median seconds, all times, last result)."""
    times, result = [], None
    for _ in range(max(1, repeats)):
        tic = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - tic)
    return statistics.median(times), times, result


def _peak_rss_mb(pid):
    """Peak resident set size of a running process (``VmHWM`` in /proc), MB; NaN if unknown."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return float("nan")


def run_python(code: str, timeout: float | None = None, env: dict | None = None) -> dict:
    """Run ``code`` in a fresh interpreter; it must print one JSON object as its last line.

    Returns that object plus ``wall`` (s), ``timed_out`` (bool), ``returncode`` and
    ``peak_rss_mb``: the child's own peak resident set size, read by the child
    itself (``RUSAGE_SELF``) when it finishes, or from ``/proc/PID/status``
    (``VmHWM``) just before it is killed at the time cap. ``children_rss_mb`` is
    ``RUSAGE_CHILDREN`` of this process after the child was reaped (the largest
    child so far, a cross-check).
    """
    prelude = "import json, resource\n"
    epilogue = ("\nimport sys as _s; _s.stdout.flush()\n"
                "print(json.dumps({'_self_rss_kb': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}))\n")
    tic = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", prelude + textwrap.dedent(code) + epilogue],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                            env={**os.environ, **(env or {})})
    peak = float("nan")
    try:
        while True:
            try:
                stdout, stderr = proc.communicate(timeout=1.0)
                break
            except subprocess.TimeoutExpired:
                peak = _peak_rss_mb(proc.pid)
                if timeout is not None and time.perf_counter() - tic > timeout:
                    proc.kill()
                    proc.communicate()
                    return {"wall": time.perf_counter() - tic, "timed_out": True, "returncode": None,
                            "peak_rss_mb": peak}
    except BaseException:
        proc.kill()
        raise
    wall = time.perf_counter() - tic
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    out = {}
    for line in stdout.splitlines():
        if line.startswith("{"):
            out.update(json.loads(line))
    out.update(wall=wall, timed_out=False, returncode=proc.returncode,
               peak_rss_mb=out.pop("_self_rss_kb", float("nan") if peak != peak else peak * 1024) / 1024.0,
               children_rss_mb=children / 1024.0)
    if proc.returncode != 0:
        out["stderr"] = stderr[-2000:]
    return out


def verdict(ok: bool) -> str:
    return "PASS" if ok else "MISS"


def add_cold_solve_arguments(parser):
    """The flags of the cold-solve comparisons (``bench_solver_option``, ``bench_newton_floor``):
    ``--levels``, ``--repeats``, ``--postures`` and ``--quick``; :func:`cold_solve_defaults` fills them."""
    parser.add_argument("--levels", default=None, help="comma-separated (default ultra-thin,reference,fine10k; "
                                                       "--quick: coarse,medium)")
    parser.add_argument("--repeats", type=int, default=None, help="solves per median (default 3; --quick: 1)")
    parser.add_argument("--postures", default="standing,bent45,fours", help="paper postures (default all three)")
    parser.add_argument("--quick", action="store_true", help="coarse and medium, one repeat (make bench)")


def cold_solve_defaults(args):
    """``args`` of :func:`add_cold_solve_arguments` with its lists split and the defaults filled in."""
    args.levels = (args.levels or ("coarse,medium" if args.quick else "ultra-thin,reference,fine10k")).split(",")
    args.repeats = args.repeats or (1 if args.quick else 3)
    args.postures = args.postures.split(",")
    return args
