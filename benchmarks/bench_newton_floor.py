"""How much of a cold solve is the stick-slip front? The solve again with the sliding law smoothed (issue #21).

Usage::

    python benchmarks/bench_newton_floor.py [--levels ultra-thin,reference,fine10k] [--repeats 3]
                                            [--postures standing,bent45,fours] [--deltas 1e-4,1e-3]
    python benchmarks/bench_newton_floor.py --quick     # coarse and medium, one repeat (``make bench``)

Per level and paper posture, cold solves at the paper's Λ̄ (a new
:class:`~breastcore.forward.model.ForwardModel`, from the gravity-free shape, as
``bench_cold_factorisations``):

- ``default``: today's solver at the spec's δ;
- ``exact``: the same with a fresh factorisation at every Newton step (``reuse_factor=0``);
- ``default δ=…``: today's solver with the Chassaignac smoothing δ raised to each of ``--deltas``;
- ``Newton δ=…``: plain Newton there: a fresh factorisation of the exact Hessian at every step
  (``reuse_factor=0``, no primal-dual sliding blocks, no released nodes: ``sliding_dual`` and
  ``sliding_release`` off).

A larger δ is another model (docs/benchmarks.md, "the smoothing δ"); here it is a yardstick for the
solver: at δ = 1e-3 m the sliding force turns over about a millimetre of slip instead of a
micrometre, so what the iterations still take is mostly the large-deformation path from the
gravity-free shape. The difference to today's solver estimates what a better treatment of the
sliding law (a semismooth or active-set Newton) could save on this cold path; it is an estimate of
one smoothing, not a bound. Printed per solve: the median time, the Newton iterations, the numeric
factorisations (PARDISO's, counted at the handle, so a saddle escape's count too; ``a-b`` where
repeats differ), the largest count of negative pivots among them (PARDISO's inertia: the depth of an
indefinite phase; the steps that ``deep_indefinite_skips`` take without an exact factorisation are
not seen), the negative eigenvalues at the solution, and the **factorisation-equivalents**: time /
one factorisation of the exact Hessian at the default's solution, in the same process (issue #21 asks
for ≤ 10 on ultra-thin). Without PARDISO the counts are "—". A last table fits ``time ∝ N^p`` (N nodes,
least squares over the levels given) per posture and solver, and for the one factorisation.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import (add_cold_solve_arguments, cold_solve_defaults, fit_exponent, header,  # noqa: E402
                               print_table)
from benchmarks.bench_cold_factorisations import factorisation_seconds  # noqa: E402
from breastcore.linalg import pardiso  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.forward.options import SolverOptions  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402


class _Counter:
    """Counts PARDISO's numeric factorisations and their largest negative-pivot count while installed."""

    def __init__(self):
        self.count = self.deepest = 0
        self._factorize = None

    def reset(self):
        self.count = self.deepest = 0

    def __enter__(self):
        self._factorize = original = pardiso._Pardiso.factorize
        counter = self

        def factorize(handle, data, owner):
            negative = original(handle, data, owner)
            counter.count += 1
            counter.deepest = max(counter.deepest, negative)
            return negative
        pardiso._Pardiso.factorize = factorize
        return self

    def __exit__(self, *exc):
        pardiso._Pardiso.factorize = self._factorize


def variants(deltas):
    """``{name: (SolverOptions, Parameters)}``: today's solver and exact steps at the spec's δ, then
    today's solver and plain Newton at each raised δ (m; above ``smoothing_start``: no δ phase)."""
    exact = dataclasses.replace(SolverOptions(), reuse_factor=0.0)
    newton = dataclasses.replace(exact, sliding_dual=False, sliding_release=False)
    out = {"default": (SolverOptions(), Parameters()), "exact": (exact, Parameters())}
    for delta in deltas:
        raised = dataclasses.replace(Parameters(), smoothing=delta)
        out[f"default δ={delta:g}"] = (SolverOptions(), raised)
        out[f"Newton δ={delta:g}"] = (newton, raised)
    return out


def counted_solve(mesh, options, params, posture, counter, model_class=ForwardModel):
    """``(seconds, Newton iterations, factorisations, largest negative-pivot count, solution)`` of one
    cold solve by a new ``model_class(mesh, options)`` (its construction timed too)."""
    counter.reset()
    start = time.perf_counter()
    solution = model_class(mesh, options).solve(params, posture)
    return time.perf_counter() - start, solution.iterations, counter.count, counter.deepest, solution


def _spread(values):
    """``"n"``, or ``"a-b"`` where the repeats differ."""
    low, high = min(values), max(values)
    return str(low) if low == high else f"{low}-{high}"


def _counts(values):
    """:func:`_spread` of PARDISO's counts; "—" without PARDISO (nothing is counted)."""
    return _spread(values) if pardiso.available() else "—"


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_cold_solve_arguments(parser)
    parser.add_argument("--deltas", default="1e-4,1e-3", help="raised smoothing lengths δ, m (default 1e-4,1e-3)")
    args = cold_solve_defaults(parser.parse_args(argv))
    args.deltas = [float(d) for d in args.deltas.split(",")]
    if not all(d > Parameters().smoothing for d in args.deltas):
        parser.error(f"--deltas must exceed the spec's δ = {Parameters().smoothing:g} m")
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_newton_floor", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    cases = variants(args.deltas)
    rows, growth = [], {}          # (posture, solver) → ([nodes], [seconds]); solver None: one factorisation
    ForwardModel(mesh_level("coarse")).solve(Parameters(), paper_postures()[0])     # compile the kernels first
    with _Counter() as counter:
        for level in args.levels:
            mesh = mesh_level(level)
            for posture in (p for p in paper_postures() if p.name in args.postures):
                runs = {name: [] for name in cases}
                for _ in range(args.repeats):                         # alternated: drift hits all alike
                    for name, (options, params) in cases.items():
                        runs[name].append(counted_solve(mesh, options, params, posture, counter))
                factor = factorisation_seconds(ForwardModel(mesh), Parameters(), posture,
                                               runs["default"][0][4].position)
                _grow(growth, (posture.name, None), len(mesh.nodes), factor)
                for name, solves in runs.items():
                    seconds = statistics.median(s[0] for s in solves)
                    _grow(growth, (posture.name, name), len(mesh.nodes), seconds)
                    rows.append([level, str(len(mesh.nodes)), posture.name, name, f"{seconds:.3f}",
                                 _spread([s[1] for s in solves]), _counts([s[2] for s in solves]),
                                 _counts([s[3] for s in solves]), str(solves[0][4].negative_eigenvalues),
                                 f"{seconds / factor:.1f}", f"{1e3 * factor:.1f}"])
    print_table(["level", "nodes", "posture", "solver", "time (s)", "Newton iterations", "factorisations",
                 "largest negative-pivot count", "negative eigenvalues at the solution",
                 "factorisation-equivalents", "one factorisation (ms)"], rows,
                title=f"Cold solves at Λ̄, median of {args.repeats}, the variants alternated")
    if len(args.levels) > 1:
        print_table(["posture", "solver", "levels", "p in time ∝ N^p"],
                    [[posture, solver or "one factorisation", f"{args.levels[0]} … {args.levels[-1]}",
                      f"{fit_exponent(n, t):.2f}"] for (posture, solver), (n, t) in growth.items()],
                    title="Growth with the node count (least squares over the levels)")
    return 0


def _grow(growth, key, nodes, seconds):
    """Add one level's ``(nodes, seconds)`` to ``growth[key]``."""
    n, t = growth.setdefault(key, ([], []))
    n.append(nodes)
    t.append(seconds)


if __name__ == "__main__":
    sys.exit(main())
