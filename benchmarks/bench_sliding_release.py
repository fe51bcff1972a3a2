"""Cold solves at Λ̄ with and without the released sliding steps, alternated in one process.

Usage::

    python benchmarks/bench_sliding_release.py [--levels ultra-thin,reference,fine10k] [--repeats 3]
    python benchmarks/bench_sliding_release.py --quick     # coarse and medium, one repeat (``make bench``)

Per level and paper posture, a cold solve at the paper's Λ̄ (a new
:class:`~breastcore.forward.model.ForwardModel`, from the gravity-free shape) with
``SolverOptions(sliding_release=False)`` (the primal-dual sliding steps alone, the default
before 60e6632) and with ``sliding_release=True`` (the default since), the two alternated
``--repeats`` times in this process so that the machine's drift hits both alike. Printed:
the median times, the factorisations of each solve (counted on
:class:`~breastcore.linalg.factorization.Factorization`; the same in every repeat), the time
ratio, and ``|ΔE/E|`` between the two equilibria (round-off where both reach the same one).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table  # noqa: E402
import breastcore.linalg.factorization as factorization  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.forward.options import SolverOptions  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402


class _Counted(factorization.Factorization):
    """A factorisation that counts its instances (the solver's own class is swapped for it)."""

    count = 0

    def __init__(self, *args, **kwargs):
        type(self).count += 1
        super().__init__(*args, **kwargs)


def counted_solve(mesh, release, params, posture):
    """``(seconds, factorisations, energy)`` of one cold solve."""
    _Counted.count = 0
    start = time.perf_counter()
    solution = ForwardModel(mesh, SolverOptions(sliding_release=release)).solve(params, posture)
    return time.perf_counter() - start, _Counted.count, solution.energy


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--levels", default=None, help="comma-separated (default ultra-thin,reference,fine10k; "
                                                       "--quick: coarse,medium)")
    parser.add_argument("--repeats", type=int, default=None, help="solves per median (default 3; --quick: 1)")
    parser.add_argument("--quick", action="store_true", help="coarse and medium, one repeat (make bench)")
    args = parser.parse_args(argv)
    args.levels = (args.levels or ("coarse,medium" if args.quick else "ultra-thin,reference,fine10k")).split(",")
    args.repeats = args.repeats or (1 if args.quick else 3)
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_sliding_release", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    factorization.Factorization = _Counted        # every module looks the class up at call time
    params, rows, totals = Parameters(), [], {False: [0.0, 0], True: [0.0, 0]}
    ForwardModel(mesh_level("coarse")).solve(params, paper_postures()[0])     # compile the kernels first
    for level in args.levels:
        mesh = mesh_level(level)
        for posture in paper_postures():
            runs = {False: [], True: []}
            for _ in range(args.repeats):
                for release in (False, True):
                    runs[release].append(counted_solve(mesh, release, params, posture))
            median = {k: statistics.median(r[0] for r in v) for k, v in runs.items()}
            for k in (False, True):
                totals[k][0] += median[k]
                totals[k][1] += runs[k][0][1]
            energy_gap = abs(runs[True][0][2] / runs[False][0][2] - 1.0)
            rows.append([level, posture.name, f"{median[False]:.3f}", str(runs[False][0][1]), f"{median[True]:.3f}",
                         str(runs[True][0][1]), f"{median[True] / median[False]:.2f}", f"{energy_gap:.1e}"])
    rows.append(["all", "", f"{totals[False][0]:.2f}", str(totals[False][1]), f"{totals[True][0]:.2f}",
                 str(totals[True][1]), f"{totals[True][0] / totals[False][0]:.2f}", ""])
    print_table(["level", "posture", "no release (s)", "factorisations", "release (s)", "factorisations",
                 "time ratio", "|ΔE/E|"], rows,
                title=f"Cold solves at Λ̄, median of {args.repeats}, the two alternated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
