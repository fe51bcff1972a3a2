"""Identification time and outcome of paper Table-1 jobs under several warm-start radii.

Usage::

    python benchmarks/bench_warm_radius.py [--level medium-thin] [--radii 0.05,0.15]
                                           [--starts 2] [--offsets 0.1,0.3,0.6,0.9]

Takes the jobs of scene ``paper_table1`` (``config.yaml`` + ``config/paper.yaml``) on
one mesh level, the first ``--starts`` random starts per offset, and runs each
identification in this process (no Snakemake, so about 1 s less overhead per job than
in the workflow) once per ``MeasurementModel.warm_radius``. The inputs (mesh,
measurements) must exist: run the paper scene, or at least its ``measure`` jobs.
Each run is written to ``benchmarks/results/warm_radius/``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import RESULTS, ROOT, header, print_table  # noqa: E402
import breastcore.pipeline as pipeline  # noqa: E402
from breastcore.datasets import open_dataset  # noqa: E402
from breastcore.observation import MeasurementModel  # noqa: E402
from breastcore.workflow_config import validate_config  # noqa: E402
from breastcore.workflow_plan import Plan  # noqa: E402


def table1_runs(level, starts, offsets):
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    paper = yaml.safe_load((ROOT / "config" / "paper.yaml").read_text())
    config["run_scenes"] = paper["run_scenes"]
    config["scenes"].update(paper["scenes"])
    plan = Plan(validate_config(config, str(ROOT / "workflow" / "schemas" / "config.schema.yaml")))
    runs = [r for r in plan.scenes["paper_table1"]["runs"]
            if r["mesh"] == level and r["start"] < starts and (offsets is None or r["offset"] in offsets)]
    return plan, runs


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--level", default="medium-thin")
    parser.add_argument("--radii", default="0.05,0.15")
    parser.add_argument("--starts", type=int, default=2)
    parser.add_argument("--offsets", default=None)
    args = parser.parse_args(argv)
    header("bench_warm_radius")
    radii = [float(r) for r in args.radii.split(",")]
    offsets = [float(o) for o in args.offsets.split(",")] if args.offsets else None
    plan, runs = table1_runs(args.level, args.starts, offsets)
    out_dir = RESULTS / "warm_radius"
    out_dir.mkdir(parents=True, exist_ok=True)

    class Radius(MeasurementModel):                       # run_identify builds its own MeasurementModel
        radius = 0.05

        def __init__(self, *a, **k):
            super().__init__(*a, **{**k, "warm_radius": self.radius})

    pipeline.MeasurementModel = Radius
    rows = []
    for run in runs:
        spec = plan.jobs["identify"][run["identification"]]
        for radius in radii:
            Radius.radius = radius
            out = out_dir / f"{args.level}-{run['offset']}-{run['start']}-{radius}.nc"
            tic = time.perf_counter()
            pipeline.run_identify(spec, spec["measurements"], spec["mesh"], out)
            seconds = time.perf_counter() - tic
            with open_dataset(out) as ds:
                rows.append([run["offset"], run["start"], radius, f"{seconds:.1f}", ds.attrs["iterations"],
                             ds.attrs["forward_solves"], ds.attrs["failed_solves"],
                             f"{float(ds.attrs['branch_drift']):.1e}", f"{float(ds['cost'].values[-1]):.3e}",
                             f"{float(np.abs(ds['relative_error'].values).mean()):.3f}"])
    print_table(["offset", "start", "warm radius", "time (s)", "iterations", "solves", "failed", "drift",
                 "final cost", "mean abs. rel. error"], rows, f"Table-1 jobs on {args.level}")
    for radius in radii:
        total = sum(float(r[3]) for r in rows if r[2] == radius)
        print(f"warm radius {radius}: {total:.1f} s in all")


if __name__ == "__main__":
    main()
