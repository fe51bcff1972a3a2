"""Stability grid of the forward solve (issue #2): does every case converge or fail cleanly?

Grid (coarse mesh, R = 0.0562 m, λ_s = 5 μ_s as in the paper, t_s = 1 mm):

    λ/μ ∈ {0.1, 6.7, 100, 1e4}      μ ∈ {15, 150, 1500} Pa      μ_s ∈ {0, 160, 1600, 16000} Pa
    H/R ∈ {0.3, 0.89, 0.97}         c ∈ {0, 100, 2000} Pa       δ ∈ {1e-4, 1e-7} m
    posture ∈ {standing, bent45, fours}

Every combination (2 592 cases) by default; ``--sample N`` takes a fixed-seed
Latin-hypercube-like subsample of N cases (each of the k values of a factor
appears about N/k times; repeated cases are dropped) plus all one-at-a-time
variations from the paper's Λ̄.

Each case runs in a worker process; a case that exceeds ``--timeout`` seconds is
killed and counted as a hang. Outcomes:

- ``converged``: a solution was returned, and an independent check passed: the
  free-dof gradient norm recomputed from the returned positions with a fresh
  model is ≤ the tolerance, every position is finite, the fixed dofs are at
  their prescribed values and every tet has det F > 0;
- ``unverified``: a solution was returned but that check failed;
- ``nan``: a returned solution contains NaN/inf;
- ``solve_error``: :class:`~breastcore.forward.model.SolveError` (a clean, typed failure);
- ``crash``: any other exception; ``hang``: killed at the time cap.

Writes ``benchmarks/results/stability.csv`` (``stability_quick.csv`` with ``--quick``,
so that ``make bench`` never overwrites a full grid's table) and prints the counts,
the convergence rate and a per-value breakdown.

Usage::

    python -m breastcore.studies.stability_grid [--sample N] [--level coarse] [--timeout 120]
    python -m breastcore.studies.stability_grid --quick     # --sample 150 (``make bench``)
"""

from __future__ import annotations

import argparse
import csv
import itertools
import multiprocessing as mp
import os
import sys
import time
import traceback
from collections import Counter
from pathlib import Path

from breastcore.report.text_table import header, print_table

#: Where the case tables go by default (relative to the working directory).
RESULTS = Path("results") / "studies"

R = 0.0562
FACTORS = {
    "lam_over_mu": [0.1, 6.7, 100.0, 1e4],
    "mu": [15.0, 150.0, 1500.0],
    "mu_s": [0.0, 160.0, 1600.0, 16000.0],
    "H_over_R": [0.3, 0.89, 0.97],
    "c": [0.0, 100.0, 2000.0],
    "delta": [1e-4, 1e-7],
    "posture": ["standing", "bent45", "fours"],
}
#: The paper's Λ̄ in grid coordinates (λ/μ = 1000/150 ≈ 6.7, H/R = 0.05/0.0562 ≈ 0.89).
PAPER = {"lam_over_mu": 6.7, "mu": 150.0, "mu_s": 1600.0, "H_over_R": 0.89, "c": 100.0, "delta": 1e-4,
         "posture": "standing"}
OUTCOMES = ("converged", "unverified", "nan", "solve_error", "crash", "hang")


def full_grid():
    names = list(FACTORS)
    return [dict(zip(names, values)) for values in itertools.product(*FACTORS.values())]


def one_at_a_time():
    """Λ̄ with one factor changed at a time, every posture (the paper's neighbourhood)."""
    cases = []
    for posture in FACTORS["posture"]:
        base = dict(PAPER, posture=posture)
        cases.append(base)
        for name, values in FACTORS.items():
            if name == "posture":
                continue
            cases += [dict(base, **{name: v}) for v in values if v != base[name]]
    return cases


def sampled_grid(n, seed=20240611):
    """Fixed-seed Latin-hypercube-like subsample of ``n`` grid points plus :func:`one_at_a_time`.

    For each factor, a random permutation of ``[v_0, v_1, …]`` repeated to length ``n``
    gives that factor's column, so each of its k values appears ⌊n/k⌋ or ⌈n/k⌉ times
    before repeated cases are dropped.
    """
    import numpy as np
    rng = np.random.default_rng(seed)
    columns = {}
    for name, values in FACTORS.items():
        reps = [values[i % len(values)] for i in range(n)]
        columns[name] = [reps[i] for i in rng.permutation(n)]
    cases = [{name: columns[name][i] for name in FACTORS} for i in range(n)]
    seen, out = set(), []
    for case in cases + one_at_a_time():
        key = tuple(case[k] for k in FACTORS)
        if key not in seen:
            seen.add(key)
            out.append(case)
    return out


def parameters(case):
    from breastcore.model.parameters import Parameters
    mu, mu_s = case["mu"], case["mu_s"]
    return Parameters(R=R, H=case["H_over_R"] * R, lambda_breast=case["lam_over_mu"] * mu, mu_breast=mu,
                      lambda_skin=5.0 * mu_s, mu_skin=mu_s, chassaignac=case["c"], smoothing=case["delta"])


_MODELS = {}


def _model(level):
    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    if level not in _MODELS:
        _MODELS[level] = ForwardModel(mesh_level(level))
    return _MODELS[level]


def verify(level, params, posture, x):
    """Independent check of a returned solution; returns (ok, gradient norm, tolerance, min det F, why)."""
    import numpy as np

    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    model = ForwardModel(mesh_level(level))          # fresh: shares no state with the solver's model
    problem = model.problem(params, posture)
    tolerance = model.tolerance(params, posture)
    if not np.all(np.isfinite(x)):
        return False, float("nan"), tolerance, float("nan"), "non-finite positions"
    free = problem.assembler.free.reshape(-1, 3)
    if not np.array_equal(x[~free], problem.reference[~free]):
        return False, float("nan"), tolerance, float("nan"), "fixed dofs moved"
    det = problem.bulk.det_F(x)
    g_norm = float(np.linalg.norm(problem.gradient(problem.free(x))))
    if not det.min() > 0:
        return False, g_norm, tolerance, float(det.min()), "inverted tet"
    if not g_norm <= tolerance:
        return False, g_norm, tolerance, float(det.min()), "gradient above tolerance"
    return True, g_norm, tolerance, float(det.min()), ""


def run_case(case, level="coarse"):
    """Solve one grid case in this process and classify it (a dict row of the case table)."""
    import numpy as np

    from breastcore.forward.records import SolveError
    from breastcore.model.postures import parse_posture
    row = dict(case)
    params = parameters(case)
    posture = parse_posture(case["posture"])
    model = _model(level)
    tic = time.perf_counter()
    try:
        sol = model.solve(params, posture)
    except SolveError as err:
        row.update(outcome="solve_error", wall=time.perf_counter() - tic, iterations=err.iterations,
                   gradient_norm=err.gradient_norm, tolerance=err.tolerance, min_det_F=err.min_det_F,
                   load_factor=err.load_factor, reached_delta=err.smoothing, message=str(err)[:300])
        return row
    except Exception as err:  # noqa: BLE001 - counting crashes is the point
        row.update(outcome="crash", wall=time.perf_counter() - tic,
                   message=f"{type(err).__name__}: {err}"[:300], traceback=traceback.format_exc()[-1500:])
        return row
    wall = time.perf_counter() - tic
    nipple = model.mesh.landmarks["nipple"]
    u = sol.position[nipple] - model.reference(params.R, params.H)[nipple]
    row.update(wall=wall, iterations=sol.iterations, continuation_steps=sol.continuation_steps,
               gradient_norm=sol.gradient_norm, tolerance=sol.tolerance, min_det_F=sol.min_det_F,
               nipple_dy=float(u[1]), nipple_dz=float(u[2]), negative_pivots=sol.negative_pivots)
    values = [sol.gradient_norm, sol.energy, sol.min_det_F, sol.max_stretch]
    if not (np.all(np.isfinite(sol.position)) and np.all(np.isfinite(values))):
        row.update(outcome="nan", message="non-finite solution")
        return row
    ok, g_norm, tol, min_det, why = verify(level, params, posture, sol.position)
    row.update(outcome="converged" if ok and sol.converged else "unverified",
               verified_gradient_norm=g_norm, verified_tolerance=tol, message=why)
    return row


def _worker(level, tasks, results):
    from breastcore.linalg.pardiso import one_thread_in_forked_worker

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    one_thread_in_forked_worker()                     # forked: a multi-threaded PARDISO would hang here
    while True:
        item = tasks.get()
        if item is None:
            return
        index, case = item
        results.put((index, run_case(case, level)))


def run_all(cases, level="coarse", processes=2, timeout=120.0, progress=True):
    """Run ``cases`` in ``processes`` worker processes; a case over ``timeout`` s is killed (a hang)."""
    ctx = mp.get_context("fork")
    results = ctx.Queue()
    rows = [None] * len(cases)
    pending = list(enumerate(cases))[::-1]
    workers = {}                                       # slot -> (process, task queue, (index, start) or None)

    def start(slot):
        tasks = ctx.Queue()
        proc = ctx.Process(target=_worker, args=(level, tasks, results), daemon=True)
        proc.start()
        workers[slot] = [proc, tasks, None]

    def feed(slot):
        if pending:
            index, case = pending.pop()
            workers[slot][1].put((index, case))
            workers[slot][2] = (index, time.perf_counter())
        else:
            workers[slot][2] = None

    for slot in range(processes):
        start(slot)
        feed(slot)
    done, tic = 0, time.perf_counter()
    while any(w[2] is not None for w in workers.values()):
        try:
            index, row = results.get(timeout=1.0)
            rows[index] = row
            done += 1
            slot = next(s for s, w in workers.items() if w[2] is not None and w[2][0] == index)
            feed(slot)
            if progress and done % 50 == 0:
                print(f"  {done}/{len(cases)} cases, {time.perf_counter() - tic:.0f} s", flush=True)
        except Exception:  # queue.Empty: check the clocks
            pass
        now = time.perf_counter()
        for slot, (proc, _, running) in list(workers.items()):
            if running is not None and (now - running[1] > timeout or not proc.is_alive()):
                index = running[0]
                proc.kill()
                proc.join()
                outcome = "hang" if proc.exitcode is None or now - running[1] > timeout else "crash"
                rows[index] = dict(cases[index], outcome=outcome, wall=now - running[1],
                                   message=f"worker killed after {now - running[1]:.0f} s" if outcome == "hang"
                                   else f"worker died (exit code {proc.exitcode})")
                done += 1
                start(slot)
                feed(slot)
    for proc, tasks, _ in workers.values():
        tasks.put(None)
        proc.join(timeout=5)
        if proc.is_alive():
            proc.kill()
    return rows


def summarise(rows):
    counts = Counter(r["outcome"] for r in rows)
    print_table(["outcome", "cases", "share"],
                [[o, counts.get(o, 0), f"{100.0 * counts.get(o, 0) / len(rows):.1f} %"] for o in OUTCOMES],
                title=f"Outcomes of {len(rows)} cases")
    rate = counts.get("converged", 0) / len(rows)
    clean = (counts.get("converged", 0) + counts.get("solve_error", 0)) / len(rows)
    print(f"convergence rate: {100 * rate:.1f} %; converged or clean SolveError: {100 * clean:.1f} %")
    saddles = sum(1 for r in rows if r["outcome"] == "converged" and (r.get("negative_pivots") or 0) > 0)
    print(f"converged to a saddle (Hessian with negative pivots at the last iteration): {saddles} cases\n")
    table = []
    for name, values in FACTORS.items():
        for v in values:
            sel = [r for r in rows if r[name] == v]
            if not sel:
                continue
            c = Counter(r["outcome"] for r in sel)
            walls = sorted(r["wall"] for r in sel if r.get("wall") is not None)
            table.append([name, v, len(sel)] + [c.get(o, 0) for o in OUTCOMES] +
                         [walls[len(walls) // 2] if walls else float("nan"), walls[-1] if walls else float("nan")])
    print_table(["factor", "value", "cases", *OUTCOMES, "median s", "max s"], table, title="Per-value breakdown")
    failures = Counter((r["outcome"], (r.get("message") or "").split(" after ")[0].split(":")[-1].strip()[:60])
                       for r in rows if r["outcome"] != "converged")
    if failures:
        print_table(["outcome", "reason", "cases"], [[o, m, n] for (o, m), n in failures.most_common(15)],
                    title="Failure reasons (most common)")
    return counts


def write_csv(rows, path):
    path.parent.mkdir(parents=True, exist_ok=True)
    keys = list(FACTORS) + ["outcome", "wall", "iterations", "continuation_steps", "gradient_norm", "tolerance",
                            "verified_gradient_norm", "verified_tolerance", "min_det_F", "negative_pivots",
                            "nipple_dy", "nipple_dz",
                            "load_factor", "reached_delta", "message"]
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    print(f"case table: {os.path.relpath(path)}")


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, default=0, help="Latin-hypercube-like subsample size (0: full grid)")
    parser.add_argument("--quick", action="store_true", help="same as --sample 150 (make bench)")
    parser.add_argument("--level", default="coarse")
    parser.add_argument("--processes", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=120.0, help="per-case wall-time cap, s")
    parser.add_argument("--out", type=Path, default=None,
                        help="case table (default benchmarks/results/stability.csv; --quick: stability_quick.csv)")
    args = parser.parse_args(argv)
    args.out = args.out or RESULTS / ("stability_quick.csv" if args.quick else "stability.csv")
    return args


def main(argv=None):
    args = parse_args(argv)
    header("Stability grid", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    n = 150 if args.quick and not args.sample else args.sample
    cases = sampled_grid(n) if n else full_grid()
    print(f"{len(cases)} cases on the {args.level} mesh "
          f"({'every combination' if not n else f'subsample of {n} + one-at-a-time from Λ̄'}), "
          f"{args.processes} worker processes, time cap {args.timeout:.0f} s per case\n", flush=True)
    tic = time.perf_counter()
    rows = run_all(cases, args.level, args.processes, args.timeout)
    print(f"\nwall time {time.perf_counter() - tic:.0f} s\n")
    summarise(rows)
    write_csv(rows, args.out)
    return rows


if __name__ == "__main__":
    main()
