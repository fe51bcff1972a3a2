"""Where one paper-scene identification job spends its time: the LM run and the branch check.

Usage::

    python benchmarks/identify_job_parts.py [--jobs medium-thin:3,ultra-thin:3,...] [--repeats 3]
                                            [--results results]

Runs, in this process, the identification jobs of ``config/paper.yaml`` named as
``level:n`` (the n-th job of that level with ``cost_rtol``, in plan order) through
``breastcore.stages.identify.run_identify``, as the workflow's ``identify`` rule does, and
prints the job's time and the part spent in the final branch check (a cold re-solve of
every posture at the estimate, ``branch.check_branch``). Medians of ``--repeats``.
The datasets go to a temporary folder. Needs the scene's meshes and measurements in
``results/`` (run the paper scene, or its mesh and measure jobs, first).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks._common import header, print_table  # noqa: E402

from breastcore.inverse import branch  # noqa: E402
from breastcore.pipeline.plan import plan_from_files  # noqa: E402
from breastcore.stages.identify import run_identify  # noqa: E402


def paper_plan():
    return plan_from_files(ROOT / "config.yaml", ROOT / "config" / "paper.yaml")


def job_spec(plan, level, nth):
    specs = [spec for spec in plan.jobs["identify"].values()
             if plan.jobs["mesh"][spec["mesh"]].get("level") == level and spec["identification"].get("cost_rtol")]
    return specs[nth]


def timed_job(spec, results, out):
    """(job seconds, branch-check seconds) of one run of the job."""
    spent = []
    check = branch.check_branch

    def timed_check(*args, **kwargs):
        tic = time.perf_counter()
        try:
            return check(*args, **kwargs)
        finally:
            spent.append(time.perf_counter() - tic)

    branch.check_branch = timed_check
    try:
        tic = time.perf_counter()
        inputs = [str(Path(results) / Path(spec[key]).relative_to("results")) for key in ("measurements", "mesh")]
        run_identify(spec, *inputs, out)
        return time.perf_counter() - tic, sum(spent)
    finally:
        branch.check_branch = check


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", default="coarse:5,medium-thin:3,medium-thin:50,ultra-thin:3,ultra-thin:12")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--results", default=str(ROOT / "results"), help="the paper scene's results folder")
    args = parser.parse_args(argv)
    header("identify_job_parts")
    plan = paper_plan()
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for item in args.jobs.split(","):
            level, nth = item.split(":")
            spec = job_spec(plan, level, int(nth))
            runs = [timed_job(spec, args.results, str(Path(folder) / "identify.nc")) for _ in range(args.repeats)]
            job = statistics.median(r[0] for r in runs)
            check = statistics.median(r[1] for r in runs)
            rows.append([item, f"{job:.2f}", f"{check:.2f}", f"{100 * check / job:.0f} %"])
    print_table(["job (level:n)", "job s", "branch check s", "share"], rows,
                title=f"One identification job, median of {args.repeats}")


if __name__ == "__main__":
    main()
