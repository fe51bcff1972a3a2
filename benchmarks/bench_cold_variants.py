"""Cold solves under variants of the solver: Newton iterations, time, and which equilibrium.

Usage::

    python benchmarks/bench_cold_variants.py [--level medium-thin] [--variants default,no-delta-phase,chord0.5,...]
    python benchmarks/bench_cold_variants.py --quick      # the coarse level (``make bench``)

Five parameter points (Λ̄ and four uniform draws within ±40 %, seed 0) are solved
cold in each paper posture, on the gmsh mesh of ``--level``
(:func:`breastcore.model.mesh.mesh_level`, the mesh the workflow writes to
``results/mesh/<level>.nc``, node for node; built here, so no workflow run is needed).
``--quick`` runs the coarse level instead, unless
``--level`` is given. Variants:

- ``before-21``: the settings before issue #21 (the gravity ramp at δ = 1e-4 m, then a δ
  continuation; a fresh factorisation every Newton iteration): the reference, always run;
- ``default``: the shipped ``SolverOptions`` (today: ``no-delta-phase+chord0.5`` with
  ``dual+shift+mixed``'s three step options, inexact directions, futile shifts skipped,
  released sliding steps and no exact factorisation in the three steps after one with more than
  14 negative pivots);
- ``no-deep-skips``: ``default`` with an exact factorisation at every fresh Newton step
  (``deep_indefinite_skips = 0``), the default from 60e6632 to 4972fbe;
- ``no-release``: ``no-deep-skips`` without the released sliding steps (``sliding_release = False``),
  the default from 0ec3832 to 8605383;
- the others are ``before-21`` with one change:
- ``smoothing1e-3`` / ``smoothing1e-2``: the gravity ramp at δ = 1e-3 m / 1e-2 m
  (``smoothing_start``) instead of 1e-4 m;
- ``projected``: Newton with ``avoid_saddles=True`` from the first iteration (the step
  from the PSD-projected Hessian whenever the exact one has negative pivots);
- ``no-delta-phase``: the gravity ramp at the target δ = 1e-6 m (``smoothing_start``), so
  that no δ continuation follows;
- ``chord0.5``: Newton's chord steps (``reuse_factor = 0.5``: the last factor is reused
  while the gradient norm halves per iteration), and both together;
- ``dual+shift+mixed``: primal-dual sliding blocks, inertia shifts and single-precision
  factors (``sliding_dual``, ``inertia_shift``, ``mixed_precision_min_dofs = 0``).

``time / before-21`` is the variant's time over the reference's on the same posture, in the
same process (a warm-up solve first, so that no variant pays the compilation).

``max ΔM`` is the largest relative difference of the 15 measurements from the
reference's at the same point: a non-zero value means the variant's continuation path
ends at another local minimum of the same energy (the standing posture has several).
``ΔE range`` is the range over the points of ``(E − E_before-21) / |E_before-21|``: negative
where the variant's minimum is the lower one.
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table  # noqa: E402

import breastcore.forward.continuation as continuation  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.forward.options import SolverOptions  # noqa: E402
from breastcore.inverse.measurements import measure  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import IDENTIFIED, Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402
from breastcore.nonlinear.newton import newton  # noqa: E402

#: The solver settings before issue #21: the reference every variant is timed against.
BEFORE = {"smoothing_start": 1e-4, "reuse_factor": 0.0, "sliding_dual": False, "sliding_release": False,
          "inertia_shift": False, "mixed_precision_min_dofs": 100_000, "deep_indefinite_skips": 0}
VARIANTS = {
    "before-21": (BEFORE, newton),
    "default": ({}, newton),
    "no-deep-skips": ({"deep_indefinite_skips": 0}, newton),
    "no-release": ({"sliding_release": False, "deep_indefinite_skips": 0}, newton),
    "smoothing1e-3": ({**BEFORE, "smoothing_start": 1e-3}, newton),
    "smoothing1e-2": ({**BEFORE, "smoothing_start": 1e-2}, newton),
    "projected": (BEFORE, functools.partial(newton, avoid_saddles=True)),
    "no-delta-phase": ({**BEFORE, "smoothing_start": 1e-6}, newton),
    "chord0.5": ({**BEFORE, "reuse_factor": 0.5}, newton),
    "no-delta-phase+chord0.5": ({**BEFORE, "smoothing_start": 1e-6, "reuse_factor": 0.5}, newton),
    "dual+shift+mixed": ({**BEFORE, "sliding_dual": True, "inertia_shift": True, "mixed_precision_min_dofs": 0},
                         newton),
}


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    # None marks "not given", so that --quick only replaces the level when none was asked for.
    parser.add_argument("--level", default=None, help="mesh level (default medium-thin; with --quick coarse)")
    parser.add_argument("--variants", default="default,smoothing1e-3,projected")
    parser.add_argument("--quick", action="store_true", help="the coarse level (make bench)")
    args = parser.parse_args(argv)
    args.level = args.level or ("coarse" if args.quick else "medium-thin")
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_cold_variants", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    # The same gmsh mesh as the workflow's results/mesh/<level>.nc (mesh_level is what run_mesh
    # writes), so the benchmark no longer depends on a workflow run having happened.
    mesh = mesh_level(args.level)
    base = Parameters()
    truth = np.array([getattr(base, n) for n in IDENTIFIED])
    rng = np.random.default_rng(0)
    points = [truth] + [truth * (1 + rng.uniform(-0.4, 0.4, 6)) for _ in range(4)]
    reference, energies, rows, default_seconds = {}, {}, [], {}
    ForwardModel(mesh).solve(base, paper_postures()[0])              # warm-up: compile the kernels
    try:
        for name in ["before-21"] + [v for v in args.variants.split(",") if v != "before-21"]:
            options, minimiser = VARIANTS[name]
            continuation.newton = minimiser                          # solve_posture's Newton for this variant
            model = ForwardModel(mesh, SolverOptions(**options))
            for posture in paper_postures():
                iterations, seconds, change, gaps = [], 0.0, 0.0, []
                for i, values in enumerate(points):
                    tic = time.perf_counter()
                    solution = model.solve(base.with_identified(values), posture)
                    seconds += time.perf_counter() - tic
                    iterations.append(solution.iterations)
                    m = np.array(list(measure(mesh, solution.position, "paper15").values()))
                    reference.setdefault((posture.name, i), m)
                    change = max(change, float(np.abs(m / reference[(posture.name, i)] - 1).max()))
                    e0 = energies.setdefault((posture.name, i), solution.energy)
                    gaps.append((solution.energy - e0) / abs(e0))
                default_seconds.setdefault(posture.name, seconds)
                rows.append([name, posture.name, " ".join(map(str, iterations)), f"{seconds:.2f}",
                             f"{seconds / default_seconds[posture.name]:.2f}", f"{change:.1e}",
                             f"{min(gaps):.1e} … {max(gaps):.1e}"])
    finally:
        continuation.newton = newton
    print_table(["variant", "posture", "Newton iterations (5 points)", "time (s)", "time / before-21", "max ΔM",
                 "ΔE range"], rows,
                f"Cold solves on {args.level}")


if __name__ == "__main__":
    main()
