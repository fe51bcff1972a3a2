"""Table-1 jobs of the paper scene under forward-solver variants, side by side: time and estimates.

Usage::

    python benchmarks/bench_table1_variants.py [--level ultra-thin] [--readings cross,same]
                                               [--variants before-21,default]
                                               [--starts 1] [--offsets 0.1,0.3,0.6,0.9]
    python benchmarks/bench_table1_variants.py --quick    # coarse, 1 start per offset (``make bench``)

Takes the jobs of ``config/paper.yaml``'s two Table-1 scenes on one mesh level: ``cross``
(``paper_table1``, truth solved on the reference level) and ``same`` (``paper_table1_same``,
truth solved on the level itself), the first ``--starts`` random starts per offset. Each
identification runs in this process once per variant, the variants of a job one after the
other, so that a drift of the machine falls on all of them. A variant sets
:class:`~breastcore.forward.options.SolverOptions` keys in the job's solver spec, for the
identification's forward solves only (the truth is the workflow's):

Every variant spells out all twelve settings (``smoothing_start``, ``reuse_factor``, ``sliding_dual``,
``sliding_release``, ``inertia_shift``, ``mixed_precision_min_dofs``, ``step_rtol``,
``skip_futile_shifts``, ``deep_indefinite_skips``, the smoothing δ, ``reduced_snapshots``,
``tangent_starts``), so that its
meaning does not move with the shipped defaults:

- ``default``: today's path (no δ phase, chord steps 0.5, tangent-predictor starts after each
  Jacobian, reduced starts over 8 snapshots before the first, primal-dual sliding blocks,
  inertia shifts where they can help, single-precision factors, inexact Newton directions,
  released sliding steps, no exact factorisation in the three steps after one with more than 14
  negative pivots);
- ``no-deep-skips``: ``default`` with an exact factorisation at every fresh Newton step
  (``deep_indefinite_skips = 0``), the default path from 60e6632 to 4972fbe;
- ``no-release``: ``no-deep-skips`` without the released sliding steps (``sliding_release = False``),
  the default path from 0ec3832 to 8605383;
- ``no-tangent``: ``no-release`` without the tangent-predictor starts (``tangent_starts = False``),
  the default path from fd093bc to 0ec3832;
- ``exact-steps``: the default path of 2026-12-02: ``default`` with exact-Hessian steps, the
  PSD projection and double-precision factors on the paper's levels;
- ``before-21``: the path before issue #21: the gravity ramp at δ = 1e-4 m then a δ
  continuation to 1e-6 m, a fresh factorisation every Newton iteration, cold solves beyond
  the warm radius;
- ``chord0.5``: ``before-21`` with Newton's chord steps (``reuse_factor = 0.5``);
- ``no-delta-phase``: ``before-21`` with the gravity ramp at the target δ
  (``smoothing_start = 1e-6`` m), no δ continuation after it;
- ``no-delta-phase+chord0.5``: both;
- ``delta1e-5``, ``delta1e-4``: a model change, not a solver one: ``before-21`` with the
  Chassaignac smoothing δ = 1e-5 m or 1e-4 m instead of the spec's 1e-6 m in the
  identification's model (a shorter δ continuation, or none), while the data stay those of
  δ = 1e-6 m: the estimate's difference from the reference's is what that δ costs in accuracy;
- ``reduced4``, ``reduced8``: ``before-21`` with ``IdentificationOptions.reduced_snapshots`` = 4
  or 8: trial points beyond the warm radius start from the energy's minimiser over the span of
  the last 4 or 8 accepted equilibria's displacements
  (:func:`breastcore.forward.reduced.reduced_start`) instead of cold;
  ``reduced8+no-delta-phase+chord0.5`` is ``exact-steps``;
- ``dual``, ``shift``, ``dual+shift``, ``mixed``: ``exact-steps`` with ``SolverOptions.sliding_dual``
  (primal-dual Chassaignac blocks in Newton's step matrix), ``inertia_shift`` (a diagonal shift
  to positive definiteness before the PSD projection), both, or single-precision factors
  refined in double on every level (``mixed_precision_min_dofs = 0``); all three is ``refined-steps``;
- ``refined-steps``: the default path of 2026-12-03 (6827140 to 7915c56): every Newton direction
  refined to 1e-10 (``step_rtol``) and the inertia shifts tried at every indefinite step;
- ``inexact``, ``skip-shifts``: ``refined-steps`` with ``step_rtol = 1e-3`` (inexact Newton
  directions) or ``skip_futile_shifts``; both is ``no-tangent``.

The first variant of ``--variants`` is the reference (default: ``before-21``).
Per job it prints the time, LM iterations, forward solves, the mean |estimate/truth − 1|
over the six parameters and the largest relative difference of the estimate from the
reference variant's; then per variant the total time and its ratio to the reference's.
Inputs are found or built as in ``bench_warm_radius.py`` (``benchmarks/results/warm_radius/inputs/``);
the identifications are written to ``benchmarks/results/table1_variants/``. ``--quick``
takes the coarse level and one start per offset, unless ``--level`` or ``--starts`` are given.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import RESULTS, header, print_table  # noqa: E402
from benchmarks.bench_warm_radius import job_inputs, table1_runs  # noqa: E402

from breastcore.io.datasets import open_dataset  # noqa: E402
from breastcore.stages.identify import run_identify  # noqa: E402

#: The solver settings before issue #21, and today's.
BEFORE = {"smoothing_start": 1e-4, "reuse_factor": 0.0, "sliding_dual": False, "sliding_release": False,
          "inertia_shift": False, "mixed_precision_min_dofs": 100_000, "step_rtol": 1e-10, "skip_futile_shifts": False,
          "deep_indefinite_skips": 0}
NEW = {"smoothing_start": 1e-6, "reuse_factor": 0.5, "sliding_dual": True, "sliding_release": True,
       "inertia_shift": True, "mixed_precision_min_dofs": 0, "step_rtol": 1e-3, "skip_futile_shifts": True,
       "deep_indefinite_skips": 3}
#: The default path from 60e6632 to 4972fbe: an exact factorisation at every fresh Newton step.
UNSKIPPED = {**NEW, "deep_indefinite_skips": 0}
#: The default path from 0ec3832 to 8605383: the primal-dual sliding steps without released nodes.
UNRELEASED = {**UNSKIPPED, "sliding_release": False}
#: The default path of 2026-12-03 (6827140 to 7915c56): every direction refined, every shift tried.
REFINED = {**UNRELEASED, "step_rtol": 1e-10, "skip_futile_shifts": False}
#: The default path of 2026-12-02: exact-Hessian steps, the PSD projection, double precision.
EXACT = {**REFINED, "sliding_dual": False, "inertia_shift": False, "mixed_precision_min_dofs": 100_000}
COLD = {"reduced_snapshots": 0, "tangent_starts": False}
#: Reduced starts over 8 snapshots without the tangent predictor (the default up to 0ec3832).
REDUCED8 = {"reduced_snapshots": 8, "tangent_starts": False}
#: Variant name → (SolverOptions keys, model constants, IdentificationOptions keys) of the identification.
VARIANTS = {
    "default": (NEW, {}, {"reduced_snapshots": 8, "tangent_starts": True}),
    "no-deep-skips": (UNSKIPPED, {}, {"reduced_snapshots": 8, "tangent_starts": True}),
    "no-release": (UNRELEASED, {}, {"reduced_snapshots": 8, "tangent_starts": True}),
    "no-tangent": (UNRELEASED, {}, REDUCED8),
    "before-21": (BEFORE, {}, COLD),
    "chord0.5": ({**BEFORE, "reuse_factor": 0.5}, {}, COLD),
    "no-delta-phase": ({**BEFORE, "smoothing_start": 1e-6}, {}, COLD),
    "no-delta-phase+chord0.5": (EXACT, {}, COLD),
    "delta1e-5": (BEFORE, {"smoothing": 1e-5}, COLD),
    "delta1e-4": (BEFORE, {"smoothing": 1e-4}, COLD),
    "reduced4": (BEFORE, {}, {"reduced_snapshots": 4, "tangent_starts": False}),
    "reduced8": (BEFORE, {}, REDUCED8),
    "reduced8+no-delta-phase+chord0.5": (EXACT, {}, REDUCED8),
    "exact-steps": (EXACT, {}, REDUCED8),
    "dual": ({**EXACT, "sliding_dual": True}, {}, REDUCED8),
    "shift": ({**EXACT, "inertia_shift": True}, {}, REDUCED8),
    "dual+shift": ({**EXACT, "sliding_dual": True, "inertia_shift": True}, {}, REDUCED8),
    "mixed": ({**EXACT, "mixed_precision_min_dofs": 0}, {}, REDUCED8),
    "refined-steps": (REFINED, {}, REDUCED8),
    "inexact": ({**REFINED, "step_rtol": 1e-3}, {}, REDUCED8),
    "skip-shifts": ({**REFINED, "skip_futile_shifts": True}, {}, REDUCED8),
}
SCENES = {"cross": "paper_table1", "same": "paper_table1_same"}


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--level", default=None, help="mesh level (default ultra-thin; --quick: coarse)")
    parser.add_argument("--readings", default="cross,same", help="comma-separated of cross, same (default both)")
    parser.add_argument("--variants", default="before-21,default",
                        help=f"comma-separated of {', '.join(VARIANTS)}; the first is the reference")
    parser.add_argument("--starts", type=int, default=None, help="starts per offset (default 1)")
    parser.add_argument("--offsets", default=None, help="comma-separated (default: all of the scene)")
    parser.add_argument("--quick", action="store_true", help="coarse level, 1 start per offset (make bench)")
    args = parser.parse_args(argv)
    args.level = args.level or ("coarse" if args.quick else "ultra-thin")
    args.starts = args.starts if args.starts is not None else 1
    args.readings = args.readings.split(",")
    args.variants = args.variants.split(",")
    unknown = [r for r in args.readings if r not in SCENES] + [v for v in args.variants if v not in VARIANTS]
    if unknown:
        parser.error(f"unknown reading or variant: {', '.join(unknown)}")
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_table1_variants", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    offsets = [float(o) for o in args.offsets.split(",")] if args.offsets else None
    jobs = []
    for reading in args.readings:
        plan, runs = table1_runs(args.level, args.starts, offsets, SCENES[reading])
        jobs += [(reading, run) for run in runs]
    out_dir = RESULTS / "table1_variants"
    out_dir.mkdir(parents=True, exist_ok=True)
    inputs = job_inputs(plan, [run for _, run in jobs], RESULTS / "warm_radius" / "inputs")   # before any clock starts

    rows, totals = [], {v: 0.0 for v in args.variants}
    for reading, run in jobs:
        spec = plan.jobs["identify"][run["identification"]]
        reference = None
        for variant in args.variants:
            solver, constants, identification = VARIANTS[variant]
            job = {**spec, "solver": {**spec["solver"], **solver}, "constants": {**spec["constants"], **constants},
                   "identification": {**spec["identification"], **identification}}
            out = out_dir / f"{reading}-{args.level}-{run['offset']}-{run['start']}-{variant}.nc"
            tic = time.perf_counter()
            run_identify(job, inputs[spec["measurements"]], inputs[spec["mesh"]], out)
            seconds = time.perf_counter() - tic
            totals[variant] += seconds
            with open_dataset(out) as ds:
                estimate = ds["estimate"].values
                reference = estimate if reference is None else reference
                rows.append([reading, run["offset"], run["start"], variant, f"{seconds:.1f}", ds.attrs["iterations"],
                             ds.attrs["forward_solves"], f"{100 * float(np.abs(ds['relative_error'].values).mean()):.4g}",
                             f"{float(np.max(np.abs(estimate / reference - 1))):.1e}"])
    print_table(["reading", "offset", "start", "variant", "time (s)", "iterations", "solves",
                 "mean |error| (%)", f"max rel. diff. from {args.variants[0]}"], rows,
                f"Table-1 jobs on {args.level}")
    for variant, total in totals.items():
        print(f"{variant}: {total:.1f} s in all, {total / totals[args.variants[0]]:.2f}× {args.variants[0]}'s")


if __name__ == "__main__":
    main()
