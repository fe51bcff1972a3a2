"""Error against run time of the relative cost-decrease stop (``cost_rtol``), replayed.

Usage::

    python -m breastcore.studies.stopping_replay [--results results] [--thresholds 0.1,0.01,...]
                                         [--compare NEW_RESULTS]

An identification run with ``cost_rtol = r`` is the prefix, bit for bit, of the same run
without it, cut after the first accepted step with ``E(Λⁿ) − E(Λⁿ⁺¹) < r E(Λⁿ)``
(``tests/inverse/test_identify.py``). So the recorded histories of a run without the test
(``<results>/identify/*.nc``: cost, parameters and wall time per iteration) give, for
every ``r``, where each run would have stopped, its time up to there and its parameter
error there. The table prints, per mesh level and threshold, the identification time
(the datasets' ``wall_time`` at the stop, without the job's start-up and final solves)
and the mean |Λ/Λ_true − 1| over the six parameters and the runs.

``--compare NEW`` checks the prediction against a run made with ``cost_rtol``: each new
run is matched to the old run with the same level, initial guess and data, and must
equal its history's prefix, ending where the replay says (or going on from there by a
branch restart). It also prints the time both runs took for the iterations they share
(the machine's speed on the day) and the time of the restarts.
"""

from __future__ import annotations

import argparse
import collections
import json
from pathlib import Path

import numpy as np
import xarray as xr

from breastcore.report.text_table import header, print_table


def plateau_stop(cost, cost_rtol):
    """Iterations done when the cost_rtol test first fires, or the last iteration if never."""
    cost = np.asarray(cost, float)
    small = np.flatnonzero(cost[:-1] - cost[1:] < cost_rtol * cost[:-1]) if cost_rtol > 0 else []
    return int(small[0]) + 1 if len(small) else len(cost) - 1


def load_runs(results):
    runs = []
    for path in sorted(Path(results, "identify").glob("*.nc")):
        with xr.open_dataset(path) as ds:
            if json.loads(ds.attrs["options"]).get("fixed_iterations"):
                continue                     # the evolution runs: every iteration by design
            finite = np.isfinite(ds.cost.values)
            runs.append({"path": path, "level": ds.attrs["mesh_level"], "cost": ds.cost.values[finite],
                         "parameters": ds.parameters.values[finite], "wall_time": ds.wall_time.values[finite],
                         "truth": ds.truth.values, "restarts": int(ds.attrs["branch_restarts"]),
                         "match": (ds.attrs["mesh_level"], ds.initial.values.tobytes(), ds.target.values.tobytes())})
    return runs


def mean_error(parameters, truth):
    return float(np.mean(np.abs(parameters / truth - 1.0)))


def replay_table(runs, thresholds):
    by_level = collections.defaultdict(list)
    for run in runs:
        by_level[run["level"]].append(run)
    rows = []
    for level, group in list(by_level.items()) + [("all", runs)]:
        full_time = sum(r["wall_time"][-1] for r in group)
        full_error = np.mean([mean_error(r["parameters"][-1], r["truth"]) for r in group])
        for rtol in thresholds:
            stops = [plateau_stop(r["cost"], rtol) for r in group]
            time = sum(r["wall_time"][k] for r, k in zip(group, stops))
            error = np.mean([mean_error(r["parameters"][k], r["truth"]) for r, k in zip(group, stops)])
            early = sum(k < len(r["cost"]) - 1 for r, k in zip(group, stops))
            rows.append([level, len(group), f"{rtol:g}", early, f"{full_time:.0f}", f"{time:.0f}",
                         f"{100 * (1 - time / full_time):.0f} %", f"{100 * full_error:.1f}", f"{100 * error:.1f}"])
    print_table(["level", "runs", "cost_rtol", "stopped earlier", "time without (s)", "time with (s)", "saved",
                 "mean error without (%)", "mean error with (%)"], rows,
                title="Replayed stop at a relative cost decrease below cost_rtol")


def compare(old_runs, new_runs, cost_rtol):
    """Outcome counts of the new runs against the replay, and the time of the iterations both did."""
    old = {r["match"]: r for r in old_runs}
    counts = collections.Counter()
    same_new = same_old = restart_time = 0.0
    for new in new_runs:
        ref = old.get(new["match"])
        if ref is None:
            counts["no matching old run"] += 1
            continue
        stop = plateau_stop(ref["cost"], cost_rtol)
        n = len(new["cost"]) - 1
        upto = min(n, stop)
        prefix = np.array_equal(new["parameters"][:upto + 1], ref["parameters"][:upto + 1])
        if not prefix:
            counts["not a prefix"] += 1
            continue
        same_new += new["wall_time"][upto]
        same_old += ref["wall_time"][upto]
        if new["restarts"]:
            counts["prefix up to the replayed stop, then a branch restart"] += 1
            restart_time += new["wall_time"][-1] - new["wall_time"][upto]
        elif n == stop:
            counts["prefix, stopped where replayed"] += 1
        else:
            counts["prefix, stopped elsewhere"] += 1
    print_table(["outcome", "runs"], sorted(counts.items()), title=f"New runs (cost_rtol = {cost_rtol:g}) against the replay")
    print(f"iterations both runs did: {same_new:.0f} s now, {same_old:.0f} s before (ratio {same_new / same_old:.3f}); "
          f"after the stop, branch restarts took {restart_time:.0f} s\n")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", default="results", help="results folder of a run without cost_rtol")
    parser.add_argument("--thresholds", default="0.1,0.03,0.01,0.003,0.001")
    parser.add_argument("--compare", default=None, help="results folder of the same scenes run with cost_rtol")
    parser.add_argument("--cost-rtol", type=float, default=0.01, help="the --compare run's cost_rtol")
    args = parser.parse_args(argv)
    header("stopping_replay")
    runs = load_runs(args.results)
    replay_table(runs, [float(t) for t in args.thresholds.split(",")])
    if args.compare:
        compare(runs, load_runs(args.compare), args.cost_rtol)


if __name__ == "__main__":
    main()
