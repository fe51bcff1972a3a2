"""Identification time and outcome of paper Table-1 jobs under several warm-start radii.

Usage::

    python benchmarks/bench_warm_radius.py [--level medium-thin] [--radii 0.05,0.15]
                                           [--starts 2] [--offsets 0.1,0.3,0.6,0.9]
    python benchmarks/bench_warm_radius.py --quick    # coarse, 1 start per offset (``make bench``)

Takes the jobs of scene ``paper_table1`` (``config.yaml`` + ``config/paper.yaml``) on
one mesh level, the first ``--starts`` random starts per offset, and runs each
identification in this process (no Snakemake, so about 1 s less overhead per job than
in the workflow) once per ``IdentificationOptions.warm_radius``. ``--quick`` takes the
coarse level and one start per offset, unless ``--level`` or ``--starts`` are given.

The inputs (the level's mesh and the synthetic measurements, i.e. the truth mesh and
solve on the reference level) are the workflow's files under ``results/`` when the
paper scene has written them; the ones missing are built here by the workflow's own
stage functions (``breastcore.stages``: ``run_mesh``, ``run_solve``, ``run_measure``,
same specs) into ``benchmarks/results/warm_radius/inputs/``, so a fresh clone needs
no workflow run. Each identification is written to ``benchmarks/results/warm_radius/``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import RESULTS, ROOT, header, print_table  # noqa: E402

from breastcore.io.datasets import open_dataset  # noqa: E402
from breastcore.pipeline.config import validate_config  # noqa: E402
from breastcore.pipeline.keys import spec_key  # noqa: E402
from breastcore.pipeline.plan import Plan  # noqa: E402
from breastcore.stages.identify import run_identify  # noqa: E402
from breastcore.stages.measure import run_measure  # noqa: E402
from breastcore.stages.mesh import run_mesh  # noqa: E402
from breastcore.stages.solve import run_solve  # noqa: E402


def table1_runs(level, starts, offsets, scene="paper_table1"):
    """The plan of ``config.yaml`` + ``config/paper.yaml`` and the runs of ``scene`` on ``level``:
    the first ``starts`` starts of each offset in ``offsets`` (None: all)."""
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    paper = yaml.safe_load((ROOT / "config" / "paper.yaml").read_text())
    config["run_scenes"] = paper["run_scenes"]
    config["scenes"].update(paper["scenes"])
    plan = Plan(validate_config(config, str(ROOT / "workflow" / "schemas" / "config.schema.yaml")))
    runs = [r for r in plan.scenes[scene]["runs"]
            if r["mesh"] == level and r["start"] < starts and (offsets is None or r["offset"] in offsets)]
    return plan, runs


def ensure_input(plan, stage, path, built):
    """Absolute path of the workflow file ``path`` of ``stage``: the workflow's if it exists, else built.

    Parameters
    ----------
    plan : Plan
        The job plan that names ``path`` and holds its spec.
    stage : {"mesh", "solve", "measure"}
        The workflow stage (rule) that writes ``path``.
    path : str
        The file as the plan names it, relative to the repository.
    built : Path
        Folder of the files built here, in the same layout as the workflow's.

    Returns
    -------
    str
        ``ROOT / path`` if the workflow wrote it; otherwise the file written under
        ``built`` by the stage function the workflow's rule calls (same spec, same
        config hash), after the files it depends on, found or built the same way. A
        file built by an earlier run of this script is rebuilt, not trusted: it may
        predate a change of the code (the workflow's own files are Snakemake's to keep
        current).
    """
    existing = ROOT / path
    if existing.exists():
        return str(existing)
    out = str(built / path)                               # str: run_measure stores its input's path as an attribute
    spec = plan.jobs[stage][path]
    if stage == "mesh":
        tic = time.perf_counter()
        run_mesh(spec, out, spec_key(spec))
    elif stage == "solve":
        mesh = ensure_input(plan, "mesh", spec["mesh"], built)
        tic = time.perf_counter()
        run_solve(spec, mesh, out, spec_key(spec))
    elif stage == "measure":
        solution = ensure_input(plan, "solve", spec["solution"], built) if "solution" in spec else None
        tic = time.perf_counter()
        run_measure(spec, solution, out, spec_key(spec))
    else:
        raise ValueError(f"no builder for stage {stage!r}")
    print(f"built {os.path.relpath(out, ROOT)} ({stage}, {time.perf_counter() - tic:.1f} s)", flush=True)
    return out


def job_inputs(plan, runs, built) -> dict:
    """``{plan path: file to read}`` of the measurements and meshes of ``runs``, found or built (:func:`ensure_input`)."""
    inputs = {}
    for run in runs:
        spec = plan.jobs["identify"][run["identification"]]
        for stage, key in (("measure", "measurements"), ("mesh", "mesh")):
            if spec[key] not in inputs:
                inputs[spec[key]] = ensure_input(plan, stage, spec[key], built)
    return inputs


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    # None marks "not given": --quick fills in only what was not asked for.
    parser.add_argument("--level", default=None, help="mesh level (default medium-thin; --quick: coarse)")
    parser.add_argument("--radii", default="0.05,0.15")
    parser.add_argument("--starts", type=int, default=None, help="starts per offset (default 2; --quick: 1)")
    parser.add_argument("--offsets", default=None, help="comma-separated (default: all of the scene)")
    parser.add_argument("--quick", action="store_true", help="coarse level, 1 start per offset (make bench)")
    args = parser.parse_args(argv)
    args.level = args.level or ("coarse" if args.quick else "medium-thin")
    args.starts = args.starts if args.starts is not None else (1 if args.quick else 2)
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_warm_radius", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    radii = [float(r) for r in args.radii.split(",")]
    offsets = [float(o) for o in args.offsets.split(",")] if args.offsets else None
    plan, runs = table1_runs(args.level, args.starts, offsets)
    out_dir = RESULTS / "warm_radius"
    out_dir.mkdir(parents=True, exist_ok=True)
    built = out_dir / "inputs"
    inputs = job_inputs(plan, runs, built)                # resolved before any clock starts

    rows = []
    for run in runs:
        spec = plan.jobs["identify"][run["identification"]]
        for radius in radii:                              # the radius is an identification option
            job = {**spec, "identification": {**spec["identification"], "warm_radius": radius}}
            out = out_dir / f"{args.level}-{run['offset']}-{run['start']}-{radius}.nc"
            tic = time.perf_counter()
            run_identify(job, inputs[spec["measurements"]], inputs[spec["mesh"]], out)
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
