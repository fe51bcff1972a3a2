"""What the scenes of a config would take from scratch, projected from a preview run's job times.

Usage::

    python -m breastcore.studies.scene_projection [--config config.yaml config/paper.yaml] [--workdir .] [--cores 2]

A preview (``config/preview.yaml``: the first ``max_starts`` random starts of every cell)
runs some of a scene's jobs under the keys of the full run. This builds the full plan of
``--config`` (the files as :func:`~breastcore.pipeline.plan.plan_from_files` merges them,
with the results folder they name, resolved from ``--workdir``), reads the ``benchmark:``
seconds of every job that the preview ran, and projects each group of jobs (scene, stage,
mesh level) as its measured mean times its number of jobs. A job that several scenes share
(a mesh, a truth solve) counts once, in the first scene of ``run_scenes`` that uses it.
The scene summaries, figures and report pages (about a second each) are not counted.

Run it in the folder of the preview run, with the config files of the full run.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections import defaultdict
from pathlib import Path

from breastcore.pipeline.batches import identification_seconds
from breastcore.pipeline.logs import benchmark_seconds
from breastcore.pipeline.plan import plan_from_files
from breastcore.report.text_table import header, print_table


def scene_groups(plan, workdir: Path) -> dict:
    """``{(scene, stage, level): [seconds or None per job]}`` over the jobs of ``plan``'s ``run_scenes``."""
    groups, counted = defaultdict(list), set()
    identified = identification_seconds(workdir / plan.results)     # batched ones get a share of their batch
    for scene in plan.run_scenes:
        for dataset in plan.scene_datasets(scene):               # "identify/<name>.nc", ...
            if dataset in counted:
                continue
            counted.add(dataset)
            stage, name = dataset.split("/", 1)
            level = plan.level_of(f"{plan.results}/{dataset}") or "patient"
            bench = workdir / plan.results / "benchmarks" / stage / f"{Path(name).stem}.tsv"
            seconds = identified.get(Path(name).stem) if stage == "identify" else benchmark_seconds(bench)
            groups[(scene, stage, level)].append(seconds)
    return dict(groups)


def project(groups: dict) -> list:
    """One row per group: scene, stage, level, jobs, measured jobs, their seconds, mean, projected seconds.

    The projection is ``mean × jobs``; NaN for a group with no measured job.
    """
    rows = []
    for (scene, stage, level), seconds in groups.items():
        measured = [s for s in seconds if s is not None]
        mean = sum(measured) / len(measured) if measured else math.nan
        rows.append([scene, stage, level, len(seconds), len(measured), sum(measured), mean, mean * len(seconds)])
    return rows


def totals(rows, cores: int) -> dict:
    """Measured and projected job seconds, the groups left unmeasured, and the wall time on ``cores``.

    The wall time is the job time over the cores, a lower bound that a run whose cores are
    all busy throughout (as Snakemake keeps them with enough ready jobs) comes close to.
    """
    projected = sum(r[7] for r in rows if not math.isnan(r[7]))
    return {"measured": sum(r[5] for r in rows), "projected": projected,
            "unmeasured": [tuple(r[:3]) for r in rows if r[4] == 0], "wall": projected / cores}


def _seconds(x) -> str:
    return "—" if math.isnan(x) else f"{x:,.0f}" if x >= 100 else f"{x:.2f}"


def _positive_int(text):
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be ≥ 1, got {value}")
    return value


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", nargs="+", default=["config.yaml", "config/paper.yaml"],
                        help="the full run's config files, later ones over earlier (default config.yaml "
                             "config/paper.yaml)")
    parser.add_argument("--workdir", type=Path, default=Path("."), help="where the preview ran (default .)")
    parser.add_argument("--cores", type=_positive_int, default=2, help="cores of the projected run, ≥ 1 (default 2)")
    args = parser.parse_args(argv)
    configs = [args.workdir / c for c in args.config]
    missing = [str(c) for c in configs if not c.is_file()]
    if missing:
        parser.error(f"no such config file: {', '.join(missing)}")
    header("scene_projection", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    plan = plan_from_files(*configs)
    rows = project(scene_groups(plan, args.workdir))
    if not any(r[4] for r in rows):
        parser.error(f"no job of these scenes has a benchmark file under {args.workdir / plan.results / 'benchmarks'}: "
                     "run this in the preview's folder, with the config files of the full run")
    print_table(["scene", "stage", "level", "jobs", "measured", "measured s", "mean s", "projected s"],
                [r[:5] + [_seconds(x) for x in r[5:]] for r in rows])
    t = totals(rows, args.cores)
    print(f"job time: {t['measured']:.0f} s measured, {t['projected']:.0f} s projected; "
          f"wall time on {args.cores} cores ≥ {t['wall'] / 60:.0f} min (job time / cores)")
    if t["unmeasured"]:
        print("not projected (no job measured): " + ", ".join("/".join(g) for g in t["unmeasured"]))
    return t


if __name__ == "__main__":
    main()
