"""Identification study (issue #3): inverse crime, no inverse crime, noise and coverage.

Usage::

    python benchmarks/study_identification.py crime [--n 20] [--seed 1]
    python benchmarks/study_identification.py mesh  [--levels coarse,...] [--timeout 600]
    python benchmarks/study_identification.py misfit [--levels coarse,...]
    python benchmarks/study_identification.py noise [--n 50] [--seed 3]
    python benchmarks/study_identification.py all

Every table is printed as Markdown; the raw outcomes go to
``benchmarks/results/identification_<study>.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import contextlib  # noqa: E402

from benchmarks._common import RESULTS, header, print_table, run_python, verdict  # noqa: E402
from benchmarks._ident import (  # noqa: E402
    LEVELS,
    NAMES,
    PAPER_ANNEX,
    PAPER_TABLE1_COARSE,
    TRUTH,
    child_code,
    forward_model,
    options,
    pct,
    random_starts,
    run,
    truth_measurements,
)

from breastcore.inverse.measurements import QUANTITIES  # noqa: E402
from breastcore.model.postures import PAPER_POSTURES  # noqa: E402

PAPER_POSTURES_NAMES = tuple(PAPER_POSTURES)


START_30 = TRUTH * np.array([1.3, 0.7, 0.7, 1.3, 1.3, 0.7])


def save(name, data):
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"identification_{name}.json").write_text(json.dumps(data, indent=1))


def study_crime(n=20, seed=1, gn_iterations=25, fd_step=1e-4, tol=1e-4):
    """Task 1: coarse truth, coarse identification, ``n`` starts within ±60 %."""
    target = truth_measurements("coarse")
    starts = random_starts(n, 0.6, seed)
    lm, gn = options("lm", "implicit"), options("gauss-newton", "fd", fd_step=fd_step, max_iterations=gn_iterations)
    methods = {"lm+implicit": (lm, contextlib.nullcontext),
               "gauss-newton+fd": (gn, contextlib.nullcontext)}
    out = {}
    for label, (opts, patch) in methods.items():
        rows, runs = [], []
        for k, start in enumerate(starts):
            with patch():
                r = run("coarse", target, start, opts)
            r["recovered"] = bool(r["max_rel_error"] <= tol)
            runs.append(r)
            rows.append([k, pct(np.abs(start / TRUTH - 1).max()), "yes" if r["success"] else "no",
                         "yes" if r["recovered"] else "no", r["max_rel_error"], r["iterations"],
                         r["time"], r["forward_solves"], r["failed_solves"], r["cost"]])
        n_ok = sum(r["recovered"] for r in runs)
        print_table(["start", "max start offset %", "converged", f"recovered ≤{tol:g}", "max rel error",
                     "iterations", "time s", "posture solves", "failed solves", "final E"], rows,
                    title=f"Inverse crime, coarse, {label}" +
                    (f" (fd_step {fd_step:g}, max_iterations {gn_iterations})" if "gauss" in label else ""))
        times = [r["time"] for r in runs]
        print(f"{label}: recovered {n_ok}/{n} to ≤ {tol:g} relative in every parameter; "
              f"median time {np.median(times):.3g} s, total {np.sum(times):.3g} s\n")
        out[label] = dict(runs=runs, recovered=n_ok)
    for label in list(out)[:1]:
        ok = out[label]["recovered"]
        print(f"target ≥ {n - 1}/{n} recovered, {label}: {ok}/{n} {verdict(ok >= n - 1)}")
    print()
    out["starts"] = starts.tolist()
    save("crime", out)
    return out


def study_mesh(levels=LEVELS, timeout=600.0):
    """Task 2: truth on the reference level meshed by gmsh at the true (R, H); identify on coarser levels."""
    target = truth_measurements("reference", direct_gmsh=True)
    print("truth: cold Newton solve on mesh_cap(R̄, H̄, LEVEL_MESH_SIZE['reference']); start: Λ̄ × "
          f"{np.round(START_30 / TRUTH, 3).tolist()}\n")
    rows = [["paper (Table 1, coarse, 25 it.)", *PAPER_TABLE1_COARSE, "—", "—", "—", "—", "—"]]
    out = {"target": target.tolist(), "start": START_30.tolist(), "levels": {}}
    for level in levels:
        variants = [("ours", None)]
        for label, radius in variants:
            r = run_python(child_code(level, target, START_30, options("lm", "implicit")),
                           timeout=timeout)
            out["levels"][f"{level}/{label}"] = r
            name = f"{label}, {level}"
            if r.get("timed_out") or not r.get("ok", False):
                why = f"dropped: > {timeout:g} s" if r.get("timed_out") else \
                    r.get("error", r.get("stderr", "failed"))[-200:]
                print(f"{name}: {why}", flush=True)
                rows.append([name, *["—"] * 6, "—", "—", r["wall"], "—", why])
                continue
            print(f"{name}: {r['time']:.3g} s, max |error| {pct(r['max_rel_error']):.3g} %", flush=True)
            rows.append([name, *[pct(abs(e)) for e in r["rel_error"]], r["cost"], r["iterations"],
                         r["time"], r["forward_solves"], "converged" if r["success"] else r["message"]])
            save("mesh", out)
    print()
    print_table(["", *[f"{p} %" for p in NAMES], "final E", "iterations", "time s", "posture solves", "status"],
                rows, title="No inverse crime: |parameter error| % by identification level (truth: reference, "
                            "gmsh at true R, H)")
    save("mesh", out)
    return out


def study_misfit(levels=LEVELS):
    """Discretisation misfit at Λ̄: each level's M(Λ̄) against the reference truth of the mesh study."""
    target = truth_measurements("reference", direct_gmsh=True)
    rows = []
    for level in levels:
        rel = truth_measurements(level) / target - 1.0
        worst = np.unravel_index(np.argmax(np.abs(rel)), rel.shape)
        rows.append([level, float(np.sum(rel**2)), pct(np.abs(rel).max()),
                     f"{PAPER_POSTURES_NAMES[worst[0]]} {QUANTITIES[worst[1]]}",
                     pct(np.sqrt(np.mean(rel**2)))])
    print_table(["level", "E(Λ̄)", "max abs(M/M̄ − 1) %", "where", "rms %"], rows,
                title="Discretisation misfit at the true Λ̄: level vs reference truth (gmsh at true R, H)")
    return rows


def study_noise(n=50, seed=3, spread=0.5, noise=0.10):
    """Task 3: coarse truth, uniform ±10 % relative noise on every measurement, ±50 % starts.

    Runs the library's LM (initial trust radius 0.5, branch check) with the implicit Jacobian.
    """
    patch = contextlib.nullcontext
    target = truth_measurements("coarse")
    rng = np.random.default_rng(seed)
    starts = random_starts(n, spread, seed + 1000)
    noises = rng.uniform(-noise, noise, (n,) + target.shape)
    sigma_like = noise / np.sqrt(3.0)
    sigmas = (sigma_like, 0.10)
    runs, clean = [], []
    for k in range(n):
        with patch():
            r = run("coarse", target * (1.0 + noises[k]), starts[k], options("lm", "implicit"), noise_cov=sigmas)
            runs.append(r)
            clean.append(run("coarse", target, starts[k], options("lm", "implicit")))
        print(f"case {k:2d}: converged {r['success']}, max |error| {pct(r['max_rel_error']):.3g} %, "
              f"{r['iterations']} it., {r['time']:.3g} s; noiseless max |error| {pct(clean[-1]['max_rel_error']):.2g} %",
              flush=True)
    err = np.array([r["rel_error"] for r in runs])
    err_clean = np.array([r["rel_error"] for r in clean])
    conv = np.array([r["success"] for r in runs])
    print()
    rows = [["ours, noiseless (same starts)", *[pct(np.nanmean(np.abs(err_clean[:, j]))) for j in range(6)],
             pct(np.nanmean(np.abs(err_clean))), PAPER_ANNEX["noiseless"]],
            ["ours, ±10 % uniform noise", *[pct(np.nanmean(np.abs(err[:, j]))) for j in range(6)],
             pct(np.nanmean(np.abs(err))), PAPER_ANNEX["noisy"]],
            ["ours, ±10 % noise, median", *[pct(np.nanmedian(np.abs(err[:, j]))) for j in range(6)],
             pct(np.nanmedian(np.abs(err))), "—"]]
    print_table(["", *[f"{p} %" for p in NAMES], "overall %", "paper overall %"], rows,
                title=f"Noise: mean |parameter error| over {n} cases, coarse truth and coarse identification "
                      f"(converged {int(conv.sum())}/{n}; noiseless converged "
                      f"{sum(r['success'] for r in clean)}/{n})")
    rows = []
    for sigma in sigmas:
        cov = np.array([r[f"covered_{sigma:.6g}"] for r in runs], float)
        half = np.array([r[f"halfwidth_{sigma:.6g}"] for r in runs], float)
        label = f"σ = {sigma:.4g}" + (" (= 0.1/√3, like-for-like)" if sigma == sigma_like else " (default)")
        rows.append([label, *[pct(cov[:, j].mean()) for j in range(6)], pct(cov.mean())])
        rows.append([label + ", median 95 % half-width in ln Λ", *[np.median(half[:, j]) for j in range(6)], "—"])
    print_table(["interval model", *[f"{p}" for p in NAMES], "all"], rows,
                title="Coverage: % of cases whose 95 % interval contains the truth (target ≈ 95 %)")
    save("noise", dict(runs=runs, noiseless=clean, starts=starts.tolist(), noise=noises.tolist(), sigmas=sigmas))
    return runs


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("study", choices=("crime", "mesh", "misfit", "noise", "all"))
    parser.add_argument("--n", type=int, default=None, help="number of cases (crime 20, noise 50)")
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--levels", default=",".join(LEVELS))
    parser.add_argument("--timeout", type=float, default=600.0, help="per level, s (mesh study)")
    args = parser.parse_args(argv)
    header("identification study", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    forward_model("coarse")
    if args.study in ("crime", "all"):
        study_crime(n=args.n or 20, seed=1 if args.seed is None else args.seed)
    if args.study in ("mesh", "all"):
        study_mesh(tuple(args.levels.split(",")), args.timeout)
    if args.study in ("misfit", "all"):
        study_misfit(tuple(args.levels.split(",")))
    if args.study in ("noise", "all"):
        study_noise(n=args.n or 50, seed=3 if args.seed is None else args.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
