"""What a warm start costs as the parameters move away from the solved state, against a cold solve.

Usage::

    python benchmarks/bench_warm_distance.py [--level ultra-thin] [--points 3] [--steps 0.01,0.02,0.05,0.1,0.3]
                                             [--chains 3,6] [--smoothing 1e-6]
    python benchmarks/bench_warm_distance.py --quick      # coarse, 2 points (``make bench``)

Issue #21 asked for "no cold solve where a nearby equilibrium is known": a parameter
homotopy from the last solved state. This measures whether that pays. From each base point
Λ⁰ (Λ̄ and uniform draws within ±20 % with H < R, seed 0) and a fixed random direction ``d``
per point (each |d_j| in [0.5, 1], max |d_j| = 1; R up and H down, so that H < R holds along
the path: the study covers that orthant of directions only), the three paper postures are
solved at ``Λ = Λ⁰ exp(s d)`` for each step ``s`` of ``--steps``:

- ``cold``: from the reference state (the path that defines ``M(Λ)``);
- ``warm``: one solve from the equilibria at Λ⁰ (``ForwardModel.solve``'s ``start``: Newton
  on the target problem, and the δ continuation from that start if it fails);
- ``chain n`` (the largest step only): ``n`` warm solves at ``Λ⁰ exp(k s d / n)``,
  ``k = 1 … n``, each from the one before: a homotopy in Λ with equal steps.

Columns: Newton iterations over the three postures, time, time over the cold solve's at the
same Λ, and ``max ΔM``, the largest relative difference of the 15 measurements from the
cold solve's at the same Λ (non-zero: the warm path ended at another equilibrium).
``--smoothing`` sets the Chassaignac smoothing δ (m) of every solve (default: the spec's
1e-6 m), to see whether a smoother sliding term makes the equilibrium unique.
``--quick`` takes the coarse level and 2 points unless ``--level`` or ``--points`` are given.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table  # noqa: E402

from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.inverse.operator import MeasurementModel  # noqa: E402
from breastcore.inverse.warm_start import WarmStarts  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import IDENTIFIED, Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--level", default=None, help="mesh level (default ultra-thin; --quick: coarse)")
    parser.add_argument("--points", type=int, default=None, help="base points (default 3; --quick: 2)")
    parser.add_argument("--steps", default="0.01,0.02,0.05,0.1,0.3", help="steps s in log Λ, comma-separated")
    parser.add_argument("--chains", default="3,6", help="substeps of the homotopies to the largest step")
    parser.add_argument("--smoothing", type=float, default=Parameters().smoothing,
                        help="Chassaignac smoothing δ of every solve, m (default: the spec's)")
    parser.add_argument("--quick", action="store_true", help="coarse, 2 points (make bench)")
    args = parser.parse_args(argv)
    args.level = args.level or ("coarse" if args.quick else "ultra-thin")
    args.points = args.points if args.points is not None else (2 if args.quick else 3)
    try:
        args.steps = sorted({float(s) for s in args.steps.split(",")})
        args.chains = sorted({int(n) for n in args.chains.split(",") if n})
    except ValueError as err:
        parser.error(f"--steps and --chains are comma-separated numbers ({err})")
    if args.points < 1 or min(args.steps) <= 0 or any(n < 2 for n in args.chains) or not args.smoothing > 0:
        parser.error("--points must be ≥ 1, every step and --smoothing > 0, and every chain ≥ 2 substeps")
    return args


def directions(count, seed=0):
    """``count`` pairs (base point Λ⁰, direction d in log Λ with max |d_j| = 1), reproducibly.

    Λ⁰ is Λ̄, then uniform draws within ±20 % of it, drawn again while H ≥ R (Λ̄ has
    H/R = 0.89, so about a fifth of the draws are not caps).
    """
    rng = np.random.default_rng(seed)
    truth = np.array([getattr(Parameters(), n) for n in IDENTIFIED])
    out = []
    for i in range(count):
        base = truth
        while i and (base is truth or base[1] >= base[0]):          # Λ̄ first, then valid draws
            base = truth * (1 + rng.uniform(-0.2, 0.2, 6))
        d = rng.choice([-1.0, 1.0], 6) * rng.uniform(0.5, 1.0, 6)
        d[0], d[1] = abs(d[0]), -abs(d[1])           # R up, H down: H < R at every step
        out.append((base, d / np.abs(d).max()))
    return out


class Solver:
    """The three paper postures of ``model`` at Λ, cold or from given equilibria; counts and clocks them."""

    def __init__(self, model, smoothing):
        self.mm = MeasurementModel(model, Parameters(smoothing=smoothing), paper_postures())

    def __call__(self, values, start=None):
        """``(solutions by posture, Newton iterations, seconds)`` of the equilibria at Λ = ``values``.

        ``start``: ``(Λ, solutions)`` of equilibria to start every posture from; None: cold.
        """
        warm = None if start is None else WarmStarts.at(np.inf, start[1], start[0])
        tic = time.perf_counter()
        solutions = self.mm.solve(values, warm)
        return solutions, sum(s.iterations for s in solutions.values()), time.perf_counter() - tic

    def measurements(self, solutions):
        """The 15 ``paper15`` measurements (SI units) of ``solutions``, posture by posture."""
        return self.mm.measure(solutions).ravel()


def main(argv=None):
    """Print the table of every solve and the median ratios to the cold solves."""
    args = parse_args(argv)
    header("bench_warm_distance", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    solve = Solver(ForwardModel(mesh_level(args.level)), args.smoothing)
    solve(directions(1)[0][0])                                   # warm-up: compile the kernels
    rows, totals = [], {}
    for point, (base, d) in enumerate(directions(args.points)):
        start = (base, solve(base)[0])
        for s in args.steps:
            values = base * np.exp(s * d)
            cold, cold_its, cold_s = solve(values)
            m_cold = solve.measurements(cold)
            runs = [("warm", [values])]
            if s == args.steps[-1]:
                runs += [(f"chain {n}", [base * np.exp(k * s * d / n) for k in range(1, n + 1)]) for n in args.chains]
            rows.append([point, f"{s:g}", "cold", cold_its, f"{cold_s:.2f}", "1.00", "0"])
            for mode, path in runs:
                previous, its, seconds = start, 0, 0.0
                for stop in path:
                    solutions, i, t = solve(stop, previous)
                    previous, its, seconds = (stop, solutions), its + i, seconds + t
                change = float(np.max(np.abs(solve.measurements(solutions) / m_cold - 1)))
                rows.append([point, f"{s:g}", mode, its, f"{seconds:.2f}", f"{seconds / cold_s:.2f}", f"{change:.1e}"])
                totals.setdefault((mode, s), []).append(seconds / cold_s)
    print_table(["point", "step s", "start", "Newton iterations", "time (s)", "time / cold", "max ΔM"], rows,
                f"Warm starts against cold solves on {args.level}, three postures, δ = {args.smoothing:g} m")
    print_table(["step s", "start", "median time / cold"],
                [[f"{s:g}", mode, f"{np.median(r):.2f}"] for (mode, s), r in totals.items()],
                "Summary over the points")


if __name__ == "__main__":
    main()
