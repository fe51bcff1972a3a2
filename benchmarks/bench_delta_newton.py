"""Newton steps of a far warm solve against the Chassaignac smoothing δ: where a trial point's cost goes.

Usage::

    python benchmarks/bench_delta_newton.py [--level medium-thin] [--deltas 1e-6,1e-5,1e-4]
    python benchmarks/bench_delta_newton.py --quick        # coarse (``make bench``)

For each δ, each posture is solved cold at Λ̄ and then warm from that equilibrium at a far
trial point, Λ̄ × (R 1.05, λ 1.15, μ 0.85, μ_s 1.15) (an LM step of the size that dominates
the paper scene's identifications). From the solver's DEBUG log of that warm solve it
prints the fresh factorisations (exact Newton steps), the chord steps, the line-search
cuts and the first gradient norms. The counts are deterministic; the time is one run
(``--repeats`` for a median).
"""

from __future__ import annotations

import argparse
import io
import logging
import re
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table  # noqa: E402

from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402

#: The far trial point, as factors of Λ̄'s parameters.
FACTORS = {"R": 1.05, "lambda_breast": 1.15, "mu_breast": 0.85, "mu_skin": 1.15}


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--level", default=None, help="mesh level (default medium-thin; --quick: coarse)")
    parser.add_argument("--deltas", default="1e-6,1e-5,1e-4", help="comma-separated smoothing lengths δ, m")
    parser.add_argument("--repeats", type=int, default=1, help="timed warm solves per case (median)")
    parser.add_argument("--quick", action="store_true", help="the coarse level")
    args = parser.parse_args(argv)
    args.level = args.level or ("coarse" if args.quick else "medium-thin")
    return args


def newton_lines(model, params, posture, start):
    """The warm solve and the Newton DEBUG lines it logged."""
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    logger = logging.getLogger("breastcore.nonlinear.newton")
    old_level = logger.level
    logger.setLevel(logging.DEBUG)
    logger.addHandler(handler)
    try:
        solution = model.solve(params, posture, start)
    finally:
        logger.removeHandler(handler)
        logger.setLevel(old_level)
    return solution, [line for line in stream.getvalue().splitlines() if "newton it=" in line]


def main(argv=None):
    args = parse_args(argv)
    header("bench_delta_newton", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    model = ForwardModel(mesh_level(args.level))
    rows = []
    for delta in (float(d) for d in args.deltas.split(",")):
        base = Parameters(smoothing=delta)
        far = base.replace(**{k: getattr(base, k) * f for k, f in FACTORS.items()})
        for posture in paper_postures():
            start = model.solve(base, posture).position
            times = []
            for _ in range(max(1, args.repeats)):
                tic = time.perf_counter()
                solution, lines = newton_lines(model, far, posture, start)
                times.append(time.perf_counter() - tic)
            norms = [float(re.search(r"\|g\|=(\S+)", line).group(1)) for line in lines]
            rows.append([f"{delta:g}", posture.name, solution.iterations,
                         sum("mode=exact" in line for line in lines), sum("mode=chord" in line for line in lines),
                         sum(" step=1 " not in line for line in lines), f"{statistics.median(times):.3f}",
                         " ".join(f"{v:.0e}" for v in norms[:8])])
    print_table(["δ (m)", "posture", "iterations", "exact steps", "chord steps", "line-search cuts", "time (s)",
                 "first |g| (N)"], rows, f"far warm solves on {args.level}")


if __name__ == "__main__":
    main()
