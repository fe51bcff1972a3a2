"""breastcore/studies/scene_projection.py: a preview's job times, projected onto the full paper scene."""

import math
from pathlib import Path

import pytest

from breastcore.pipeline.plan import plan_from_files
from breastcore.studies.scene_projection import main, project, scene_groups, totals

ROOT = Path(__file__).resolve().parents[2]
FULL = [ROOT / "config.yaml", ROOT / "config/paper.yaml"]
#: Seconds of a level's first job; the second start of each cell takes twice as long.
COST = {"coarse": 1.0, "medium": 2.0, "medium-thin": 3.0, "thin": 5.0, "very-thin": 8.0, "ultra-thin": 13.0}


def _benchmark(path: Path, seconds: float):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"s\th:m:s\n{seconds}\t0:00:01\n")


@pytest.fixture
def preview_run(tmp_path):
    """A results folder with a benchmark file for every job of the preview (2 starts a cell) but the sensitivity."""
    preview = plan_from_files(*FULL, ROOT / "config/preview.yaml")
    for scene in preview.run_scenes:
        for dataset in preview.scene_datasets(scene):
            stage, name = dataset.split("/", 1)
            if stage == "sensitivity":
                continue
            level = preview.level_of(f"{preview.results}/{dataset}")
            seconds = 0.5
            if stage == "identify":
                start = next(r["start"] for s in preview.scenes.values() if s["kind"] == "synthetic"
                             for r in s["runs"] if r["identification"].endswith(dataset))
                seconds = COST[level] * (1 + start)
            _benchmark(tmp_path / preview.results / "benchmarks" / stage / f"{Path(name).stem}.tsv", seconds)
    return tmp_path


def test_each_group_is_its_measured_mean_times_its_jobs(preview_run):
    groups = scene_groups(plan_from_files(*FULL), preview_run)
    rows = {tuple(r[:3]): r for r in project(groups)}
    for level, cost in COST.items():
        _, _, _, jobs, measured, seconds, mean, projected = rows[("paper_table1", "identify", level)]
        assert (jobs, measured) == (40, 8)                        # 4 offsets × 10 starts, 2 of each run
        assert seconds == pytest.approx(4 * 3 * cost) and mean == pytest.approx(1.5 * cost)
        assert projected == pytest.approx(40 * 1.5 * cost)
    assert rows[("paper_annex_b", "identify", "medium")][3:5] == [50, 2]


def test_shared_jobs_count_once_and_unmeasured_groups_are_named(preview_run):
    plan = plan_from_files(*FULL)
    groups = scene_groups(plan, preview_run)
    datasets = {d for scene in plan.run_scenes for d in plan.scene_datasets(scene)}
    assert sum(len(v) for v in groups.values()) == len(datasets)
    meshes = [key for key in groups if key[1] == "mesh"]
    assert len({key[2] for key in meshes}) == len(meshes)       # each level's mesh in one scene only
    t = totals(project(groups), cores=2)
    assert t["unmeasured"] == [("paper_sensitivity", "sensitivity", "very-thin")]
    assert t["wall"] == pytest.approx(t["projected"] / 2)
    assert not math.isnan(t["projected"])


def test_the_command_prints_the_table_and_the_projection(preview_run, capsys):
    t = main(["--workdir", str(preview_run), "--config", str(FULL[0]), str(FULL[1])])
    out = capsys.readouterr().out
    assert "| paper_table1 " in out and f"{t['projected']:.0f} s projected" in out
    assert "not projected (no job measured): paper_sensitivity/sensitivity/very-thin" in out


@pytest.mark.parametrize("args, message", [
    (["--cores", "0"], "must be ≥ 1"),
    (["--config", "no-such.yaml"], "no such config file"),
])
def test_bad_arguments_are_refused_with_a_reason(tmp_path, capsys, args, message):
    with pytest.raises(SystemExit) as stop:
        main(["--workdir", str(tmp_path), *args])
    assert stop.value.code == 2 and message in capsys.readouterr().err


def test_a_folder_without_the_previews_benchmarks_is_refused(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--workdir", str(tmp_path), "--config", str(FULL[0]), str(FULL[1])])
    assert stop.value.code == 2 and "no job of these scenes has a benchmark file" in capsys.readouterr().err
