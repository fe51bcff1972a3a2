"""Identification benchmarks (issue #3): run times against the paper, and the Jacobian's cost.

Usage::

    python benchmarks/bench_identify.py times    [--levels coarse,ultra-thin] [--paper-iterations 10]
    python benchmarks/bench_identify.py jacobian [--levels coarse,ultra-thin]
    python benchmarks/bench_identify.py [all]          # both; ``all`` is the default
    python benchmarks/bench_identify.py --quick        # both, coarse only (``make bench``)

``times``: inverse-crime data (truth on the identification level), three fixed
starts 30 % off (``_ident.STARTS_30``), one run each; the median is reported, also in
units of one factorisation of the level's standing Hessian timed in the same process before
and after the runs (``bench_cold_factorisations.factorisation_seconds``; their mean), since the
shared machine's speed drifts by tens of percent within an hour.
``lm``+``implicit`` with Newton forward solves (beyond coarse also with the postures
in 2 processes), against the paper's method
(non-linear CG forward solves, forward-difference Jacobian, Gauss–Newton), which
is capped: coarse only and ``--paper-iterations`` (default 10) iterations.
``jacobian``: one implicit Jacobian against one forward solve of the three postures.

``--quick`` runs both on coarse only, the paper's method capped at one iteration
(``--paper-iterations 1``) and 300 s per run, each unless given explicitly; its
results go to ``benchmarks/results/identification_*_quick.json`` so that a quick run
never overwrites a full one.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import RESULTS, header, print_table, run_python, timed, verdict  # noqa: E402
from benchmarks.bench_cold_factorisations import factorisation_seconds  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402
from breastcore.inverse.warm_start import WarmStarts  # noqa: E402
from benchmarks._ident import (  # noqa: E402
    PAPER_TIME,
    STARTS_30,
    TRUTH,
    child_code,
    forward_model,
    measurement_model,
    options,
    run,
    truth_measurements,
)

TARGET_TIME = {"coarse": 3.0, "ultra-thin": 30.0}        # s, issue #3


def save(name, data):
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"identification_{name}.json").write_text(json.dumps(data, indent=1))


def bench_times(levels=("coarse", "ultra-thin"), paper_iterations=10, paper_timeout=900.0, suffix=""):
    out = {}
    summary = []
    for level in levels:
        forward_model(level)                                   # mesh outside the timings
        target = truth_measurements(level)
        unit_before = factorisation_unit(level)
        variants = [("lm+implicit", 1)] + ([("lm+implicit, 2 processes", 2)] if level != "coarse" else [])
        level_rows = []
        for label, processes in variants:
            runs = []
            for factors in STARTS_30:
                runs.append(run(level, target, TRUTH * np.array(factors), options("lm", "implicit"),
                                processes=processes))
                print(f"{level} {label} start {factors}: {runs[-1]['time']:.3g} s, "
                      f"max rel error {runs[-1]['max_rel_error']:.2g}", flush=True)
            out[f"{level}/{label}"] = runs
            med = statistics.median(r["time"] for r in runs)
            level_rows.append([level, label, *[r["time"] for r in runs], med, None,
                               max(r["max_rel_error"] for r in runs),
                               statistics.median(r["iterations"] for r in runs),
                               statistics.median(r["forward_solves"] for r in runs),
                               TARGET_TIME.get(level), PAPER_TIME.get(level),
                               verdict(med <= TARGET_TIME[level]) if level in TARGET_TIME else "—"])
        unit_after = factorisation_unit(level)
        unit = 0.5 * (unit_before + unit_after)
        print(f"{level}: one factorisation {1e3 * unit_before:.1f} ms before the runs, {1e3 * unit_after:.1f} ms after",
              flush=True)
        for row in level_rows:
            row[6] = f"{row[5] / unit:.0f}"
        summary.extend(level_rows)
        if level == "coarse" and paper_iterations:
            opts = options("gauss-newton", "fd", fd_step=1e-4, max_iterations=paper_iterations)
            runs = []
            for factors in STARTS_30:
                r = run_python(child_code(level, target, TRUTH * np.array(factors), opts, solver="cg"),
                               timeout=paper_timeout)
                if r.get("timed_out"):
                    r.update(time=r["wall"], max_rel_error=float("nan"), iterations=float("nan"),
                             forward_solves=float("nan"))
                runs.append(r)
                print(f"{level} paper method start {factors}: {r['time']:.3g} s"
                      + (" (timed out)" if r.get("timed_out") else f", final E {r['cost']:.3g}, "
                         f"max rel error {r['max_rel_error']:.2g}"), flush=True)
            out[f"{level}/paper"] = runs
            med = statistics.median(r["time"] for r in runs)
            summary.append([level, f"paper: cg solves + fd (1e-4) + gauss-newton, ≤ {paper_iterations} it.",
                            *[r["time"] for r in runs], med, f"{med / unit:.0f}", max(r["max_rel_error"] for r in runs),
                            statistics.median(r["iterations"] for r in runs),
                            statistics.median(r["forward_solves"] for r in runs), "—", PAPER_TIME.get(level), "—"])
    print()
    print_table(["level", "method", "run 1 s", "run 2 s", "run 3 s", "median s", "median / factorisation",
                 "max rel error",
                 "median iterations", "median posture solves", "target s", "paper s", "verdict"], summary,
                title="Identification wall time, inverse-crime data, three fixed starts 30 % off")
    lm = {}
    for row in summary:                                        # the fastest lm variant per level
        if row[1].startswith("lm+implicit"):
            lm[row[0]] = min(row[5], lm.get(row[0], float("inf")))
    for row in summary:
        if row[1].startswith("paper"):
            print(f"ratio paper method / lm+implicit on {row[0]}: {row[5] / lm[row[0]]:.3g} "
                  f"(paper method capped at {paper_iterations} iterations)")
    for level, t in lm.items():
        if level in PAPER_TIME:
            print(f"ratio paper's published time / ours on {level}: {PAPER_TIME[level] / t:.3g}")
    print()
    save("times" + suffix, out)
    return summary


def factorisation_unit(level):
    """Median time of one factorisation of the standing Hessian at Λ̄'s gravity-free shape on ``level`` (s)."""
    model = forward_model(level)
    params = Parameters()
    return factorisation_seconds(model, params, paper_postures()[0], model.reference(params.R, params.H))


def bench_jacobian(levels=("coarse", "ultra-thin"), repeats=5, cold_repeats=3, suffix=""):
    rows = []
    for level in levels:
        forward_model(level)
        mm = measurement_model(level)
        t_cold, _, sols = timed(lambda: measurement_model(level).solve(TRUTH), cold_repeats)
        warm = WarmStarts.at(mm.warm_radius, sols, TRUTH)
        near = TRUTH * (1 + 1e-4)
        t_warm, _, _ = timed(lambda: mm.solve(near, warm), repeats)
        t_jac, _, _ = timed(lambda: mm.implicit_jacobian(TRUTH, sols), repeats)
        t_fd, _, _ = timed(lambda: mm.fd_jacobian(TRUTH, sols, 1e-4), cold_repeats)
        rows.append([level, len(mm.model.mesh.nodes), t_cold, t_warm, t_jac, t_fd, t_jac / t_cold, t_jac / t_warm,
                     t_fd / t_jac, verdict(t_jac <= 3 * t_cold)])
        print(f"{level}: done", flush=True)
    print()
    print_table(["level", "nodes", "cold solve s", "warm solve s", "implicit J s", "fd J s",
                 "J / cold solve", "J / warm solve", "fd J / implicit J", "J ≤ 3 cold solves"], rows,
                title="One Jacobian vs one forward solve of the three postures (medians; "
                      f"{cold_repeats} cold solves, {repeats} warm solves and Jacobians, {cold_repeats} fd Jacobians)")
    save("jacobian" + suffix, rows)
    return rows


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bench", nargs="?", default="all", choices=("times", "jacobian", "all"),
                        help="which benchmark (default: all)")
    # None marks "not given": --quick fills in only what was not asked for.
    parser.add_argument("--levels", default=None, help="comma-separated (default coarse,ultra-thin; --quick: coarse)")
    parser.add_argument("--paper-iterations", type=int, default=None,
                        help="cap of the paper's method (0: skip; default 10, --quick: 1)")
    parser.add_argument("--paper-timeout", type=float, default=None,
                        help="s per run of the paper's method (default 900, --quick: 300)")
    parser.add_argument("--quick", action="store_true",
                        help="coarse only, the paper's method capped at 1 iteration (make bench)")
    args = parser.parse_args(argv)
    quick = {"levels": "coarse", "paper_iterations": 1, "paper_timeout": 300.0}
    full = {"levels": "coarse,ultra-thin", "paper_iterations": 10, "paper_timeout": 900.0}
    for key, value in (quick if args.quick else full).items():
        if getattr(args, key) is None:
            setattr(args, key, value)
    return args


def main(argv=None):
    args = parse_args(argv)
    header("identification benchmarks", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    levels = tuple(args.levels.split(","))
    suffix = "_quick" if args.quick else ""
    if args.bench in ("jacobian", "all"):
        bench_jacobian(levels, suffix=suffix)
    if args.bench in ("times", "all"):
        bench_times(levels, args.paper_iterations, args.paper_timeout, suffix=suffix)
    return 0


if __name__ == "__main__":
    sys.exit(main())
