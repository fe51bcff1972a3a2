"""A cold posture solve at Λ̄ in factorisation-equivalents, per level, and its growth with N (issue #21).

Usage::

    python benchmarks/bench_cold_factorisations.py [--levels coarse,medium,thin,ultra-thin,reference,fine10k]
                                                   [--repeats 3]
    python benchmarks/bench_cold_factorisations.py --quick     # coarse, medium, ultra-thin; 1 repeat (``make bench``)

Per level and paper posture: the median time of a cold solve at the paper's Λ̄ (a new
:class:`~breastcore.forward.model.ForwardModel`, from the gravity-free shape, as
``bench_forward``), its Newton iterations, and the median time of one factorisation of
the exact Hessian at the solution, in the same process (PARDISO on one thread, the
workflow's setting). **Factorisation-equivalents** = posture time / one factorisation:
issue #21 asks for ≤ 10 on ultra-thin. The last table fits ``time ∝ N^p`` (N nodes) over
the levels given, per posture: the issue asks for p ≤ 1.3 from coarse to fine10k.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import fit_exponent, header, print_table, timed  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.linalg.factorization import Factorization  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402

FACTORISATION_REPEATS = 5


def factorisation_seconds(model, params, posture, position):
    """Median time of one numeric factorisation of the exact Hessian at ``position`` (analysis done once)."""
    problem = model.problem(params, posture)
    K = problem.hessian(problem.free(position))
    Factorization(K, problem.pattern)                          # the symbolic analysis, once per pattern
    return timed(lambda: Factorization(K, problem.pattern), FACTORISATION_REPEATS)[0]


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--levels", default=None,
                        help="comma-separated (default coarse,medium,thin,ultra-thin,reference,fine10k; "
                             "--quick: coarse,medium,ultra-thin)")
    parser.add_argument("--repeats", type=int, default=None, help="cold solves per median (default 3; --quick: 1)")
    parser.add_argument("--quick", action="store_true", help="three levels, one repeat (make bench)")
    args = parser.parse_args(argv)
    default = "coarse,medium,ultra-thin" if args.quick else "coarse,medium,thin,ultra-thin,reference,fine10k"
    args.levels = (args.levels or default).split(",")
    args.repeats = args.repeats or (1 if args.quick else 3)
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_cold_factorisations", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    params = Parameters()
    rows, growth = [], {p.name: ([], []) for p in paper_postures()}
    ForwardModel(mesh_level("coarse")).solve(params, paper_postures()[0])     # compile the kernels first
    for level in args.levels:
        mesh = mesh_level(level)
        for posture in paper_postures():
            seconds, _, solution = timed(lambda: ForwardModel(mesh).solve(params, posture), args.repeats)
            factor = factorisation_seconds(ForwardModel(mesh), params, posture, solution.position)
            rows.append([level, str(len(mesh.nodes)), posture.name, f"{seconds:.3f}", str(solution.iterations),
                         f"{1e3 * factor:.1f}", f"{seconds / factor:.0f}"])
            growth[posture.name][0].append(len(mesh.nodes))
            growth[posture.name][1].append(seconds)
            print(f"  {level} {posture.name}: {seconds:.3f} s, {solution.iterations} it, factorisation "
                  f"{1e3 * factor:.1f} ms", flush=True)
    print()
    print_table(["level", "nodes", "posture", "cold solve (s)", "Newton it", "one factorisation (ms)",
                 "factorisation-equivalents"], rows,
                title=f"Cold solve at Λ̄, median of {args.repeats}; factorisation median of {FACTORISATION_REPEATS}")
    if len(args.levels) > 1:
        print_table(["posture", "levels", "p in time ∝ N^p"],
                    [[name, f"{args.levels[0]} … {args.levels[-1]}", f"{fit_exponent(n, t):.2f}"]
                     for name, (n, t) in growth.items()], title="Growth of the cold solve time with the node count")
    return 0


if __name__ == "__main__":
    sys.exit(main())
