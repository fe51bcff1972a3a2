"""Cold solves with one solver option off and on (its default), alternated in one process.

Usage::

    python benchmarks/bench_solver_option.py [--option sliding_release] [--levels ultra-thin,reference,fine10k]
                                             [--repeats 3] [--factors 1.3,0.7,0.7,1.3,1.3,0.7]
                                             [--postures standing,bent45,fours]
    python benchmarks/bench_solver_option.py --quick     # coarse and medium, one repeat (``make bench``)

Per level and paper posture, a cold solve (a new
:class:`~breastcore.forward.model.ForwardModel`, from the gravity-free shape) at the paper's Λ̄,
or at Λ̄ × ``--factors`` (the six identified parameters), with the option off (False for a
switch, 0 for a count: the method before it) and at its default, the two alternated
``--repeats`` times in this process so that the machine's drift hits both alike. Options:
``sliding_release`` (the default; off: the primal-dual sliding steps alone, the default before
60e6632), ``deep_indefinite_skips`` (off: an exact factorisation at every fresh Newton step), or
any other boolean or integer ``SolverOptions`` field. Printed: the median times, the
factorisations of each solve (counted on :class:`~breastcore.linalg.factorization.Factorization`;
the same in every repeat), the time ratio, and ``|ΔE/E|`` between the two equilibria (round-off
where both reach the same one). This script was ``bench_sliding_release.py`` before 2026-12-04
evening; its commands there are this one's with the default option.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import add_cold_solve_arguments, cold_solve_defaults, header, print_table  # noqa: E402
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


def off_value(option):
    """The option's value that turns it off: False for a switch, 0 for a count."""
    default = getattr(SolverOptions(), option)
    if isinstance(default, bool):
        return False
    if isinstance(default, int) and default > 0:
        return 0
    raise SystemExit(f"--option {option}: not a boolean or positive integer SolverOptions field")


def counted_solve(mesh, options, params, posture):
    """``(seconds, factorisations, energy)`` of one cold solve."""
    _Counted.count = 0
    start = time.perf_counter()
    solution = ForwardModel(mesh, options).solve(params, posture)
    return time.perf_counter() - start, _Counted.count, solution.energy


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--option", default="sliding_release", help="the SolverOptions field (default sliding_release)")
    add_cold_solve_arguments(parser)
    parser.add_argument("--factors", default="1,1,1,1,1,1", help="Λ = Λ̄ × these six factors (default Λ̄)")
    args = cold_solve_defaults(parser.parse_args(argv))
    args.factors = np.array([float(f) for f in args.factors.split(",")])
    if args.factors.shape != (6,):
        parser.error("--factors takes six comma-separated numbers")
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_solver_option", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    factorization.Factorization = _Counted        # every module looks the class up at call time
    options = {"off": dataclasses.replace(SolverOptions(), **{args.option: off_value(args.option)}),
               "on": SolverOptions()}
    params = Parameters()
    params = params.with_identified(np.array(params.identified()) * args.factors)
    rows, totals = [], {k: [0.0, 0] for k in options}
    ForwardModel(mesh_level("coarse")).solve(Parameters(), paper_postures()[0])     # compile the kernels first
    for level in args.levels:
        mesh = mesh_level(level)
        for posture in (p for p in paper_postures() if p.name in args.postures):
            runs = {k: [] for k in options}
            for _ in range(args.repeats):
                for key, opts in options.items():
                    runs[key].append(counted_solve(mesh, opts, params, posture))
            median = {k: statistics.median(r[0] for r in v) for k, v in runs.items()}
            for k in options:
                totals[k][0] += median[k]
                totals[k][1] += runs[k][0][1]
            energy_gap = abs(runs["on"][0][2] / runs["off"][0][2] - 1.0)
            rows.append([level, posture.name, f"{median['off']:.3f}", str(runs["off"][0][1]), f"{median['on']:.3f}",
                         str(runs["on"][0][1]), f"{median['on'] / median['off']:.2f}", f"{energy_gap:.1e}"])
    rows.append(["all", "", f"{totals['off'][0]:.2f}", str(totals["off"][1]), f"{totals['on'][0]:.2f}",
                 str(totals["on"][1]), f"{totals['on'][0] / totals['off'][0]:.2f}", ""])
    off, on = off_value(args.option), getattr(SolverOptions(), args.option)
    print_table(["level", "posture", f"{args.option}={off} (s)", "factorisations", f"{args.option}={on} (s)",
                 "factorisations", "time ratio", "|ΔE/E|"], rows,
                title=f"Cold solves at Λ̄ × ({', '.join(f'{f:g}' for f in args.factors)}), median of {args.repeats}, "
                      f"the two alternated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
