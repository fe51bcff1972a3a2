"""How few factorisations could a cold solve take? A nearly smooth sliding law as the bound (issue #21).

Usage::

    python benchmarks/bench_newton_floor.py [--levels ultra-thin,reference,fine10k] [--repeats 3]
                                            [--postures standing,bent45,fours] [--deltas 1e-4,1e-3]
    python benchmarks/bench_newton_floor.py --quick     # coarse and medium, one repeat (``make bench``)

Per level and paper posture, cold solves at the paper's Λ̄ (a new
:class:`~breastcore.forward.model.ForwardModel`, from the gravity-free shape, as
``bench_cold_factorisations``):

- ``default``: today's solver at the spec's δ;
- ``exact``: the same with an exact factorisation at every Newton step (``reuse_factor=0``);
- ``exact δ=…``: that, with the Chassaignac smoothing δ raised to each of ``--deltas``.

A larger δ is another model (docs/benchmarks.md, "the smoothing δ"); here it is an *oracle* for the
solver: at δ = 1e-3 m the sliding term bends over a millimetre, so Newton meets no stick-slip front,
and what its iterations still take is the large-deformation path from the gravity-free shape. No
treatment of the sliding law (a semismooth or active-set Newton) can save more than the difference
to it, on this cold path. Printed per solve: the median time, the Newton iterations, the
factorisations (counted on :class:`~breastcore.linalg.factorization.Factorization`; the same in every
repeat), the most negative pivots any of them had (PARDISO's inertia: the depth of an indefinite
phase) and the **factorisation-equivalents**: time / one factorisation of the exact Hessian at the
default's solution, in the same process (issue #21 asks for ≤ 10 on ultra-thin).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table  # noqa: E402
from benchmarks.bench_cold_factorisations import factorisation_seconds  # noqa: E402
import breastcore.linalg.factorization as factorization  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.forward.options import SolverOptions  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402


class _Counted(factorization.Factorization):
    """A factorisation that counts its instances and their largest inertia (the solver's own class is
    swapped for it)."""

    count = deepest = 0

    def __init__(self, *args, **kwargs):
        type(self).count += 1
        super().__init__(*args, **kwargs)
        type(self).deepest = max(type(self).deepest, self.negative_pivots or 0)


def variants(deltas):
    """``{name: (SolverOptions, Parameters)}``: today's solver, exact steps, exact steps at each δ (m)."""
    exact = dataclasses.replace(SolverOptions(), reuse_factor=0.0)
    out = {"default": (SolverOptions(), Parameters()), "exact": (exact, Parameters())}
    for delta in deltas:                # δ above smoothing_start (the spec's δ): no δ phase, as at the spec's
        out[f"exact δ={delta:g}"] = (exact, dataclasses.replace(Parameters(), smoothing=delta))
    return out


def counted_solve(mesh, options, params, posture):
    """``(seconds, Newton iterations, factorisations, most negative pivots, solution)`` of one cold solve."""
    _Counted.count = _Counted.deepest = 0
    start = time.perf_counter()
    solution = ForwardModel(mesh, options).solve(params, posture)
    return time.perf_counter() - start, solution.iterations, _Counted.count, _Counted.deepest, solution


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--levels", default=None, help="comma-separated (default ultra-thin,reference,fine10k; "
                                                       "--quick: coarse,medium)")
    parser.add_argument("--repeats", type=int, default=None, help="solves per median (default 3; --quick: 1)")
    parser.add_argument("--postures", default="standing,bent45,fours", help="paper postures (default all three)")
    parser.add_argument("--deltas", default="1e-4,1e-3", help="raised smoothing lengths δ, m (default 1e-4,1e-3)")
    parser.add_argument("--quick", action="store_true", help="coarse and medium, one repeat (make bench)")
    args = parser.parse_args(argv)
    args.levels = (args.levels or ("coarse,medium" if args.quick else "ultra-thin,reference,fine10k")).split(",")
    args.repeats = args.repeats or (1 if args.quick else 3)
    args.postures = args.postures.split(",")
    args.deltas = [float(d) for d in args.deltas.split(",")]
    if not all(d > Parameters().smoothing for d in args.deltas):
        parser.error(f"--deltas must exceed the spec's δ = {Parameters().smoothing:g} m")
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_newton_floor", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    factorization.Factorization = _Counted        # every module looks the class up at call time
    cases = variants(args.deltas)
    rows = []
    ForwardModel(mesh_level("coarse")).solve(Parameters(), paper_postures()[0])     # compile the kernels first
    for level in args.levels:
        mesh = mesh_level(level)
        for posture in (p for p in paper_postures() if p.name in args.postures):
            runs = {name: [] for name in cases}
            for _ in range(args.repeats):                             # alternated: drift hits all alike
                for name, (options, params) in cases.items():
                    runs[name].append(counted_solve(mesh, options, params, posture))
            factor = factorisation_seconds(ForwardModel(mesh), Parameters(), posture, runs["default"][0][4].position)
            for name, solves in runs.items():
                seconds = statistics.median(s[0] for s in solves)
                rows.append([level, posture.name, name, f"{seconds:.3f}", str(solves[0][1]), str(solves[0][2]),
                             str(solves[0][3]), f"{seconds / factor:.1f}", f"{1e3 * factor:.1f}"])
    print_table(["level", "posture", "solver", "time (s)", "Newton iterations", "factorisations",
                 "most negative pivots", "factorisation-equivalents", "one factorisation (ms)"], rows,
                title=f"Cold solves at Λ̄, median of {args.repeats}, the variants alternated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
