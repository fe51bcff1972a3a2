"""Identifications run in batches (breastcore.pipeline.batches): same files, same datasets, reused either way."""

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from breastcore.pipeline.batches import JOB_LINE, identification_seconds, identify_batches
from breastcore.pipeline.config import validate_config
from breastcore.pipeline.config_files import ConfigError
from breastcore.pipeline.logs import benchmark_seconds
from breastcore.pipeline.plan import Plan
from breastcore.report.compare import compare_results

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
SCHEMA = str(ROOT / "workflow/schemas/config.schema.yaml")

# Three starts of one cell on coarse (data solved on coarse itself), LM capped at 3 iterations.
CELL = {"kind": "synthetic", "truth_mesh": "same", "meshes": ["coarse"], "offsets": [0.3], "starts": 3, "seed": 1,
        "identification": {"max_iterations": 3}}


def plan(scenes, **config):
    return Plan(validate_config({"report": {"enabled": False}, "scenes": scenes, **config}, SCHEMA))


def test_starts_of_a_cell_are_batched_in_plan_order_and_a_leftover_runs_alone():
    p = plan({"cell": CELL})
    paths = list(p.jobs["identify"])
    assert list(identify_batches(p, 2).values()) == [paths[:2]]          # the third is left over: alone
    assert list(identify_batches(p, 3).values()) == [paths]
    assert list(identify_batches(p, 10).values()) == [paths]
    assert identify_batches(p, 1) == {}
    with pytest.raises(ValueError, match="at least 1"):
        identify_batches(p, 0)


def test_only_identifications_that_differ_in_their_guess_share_a_batch():
    other = {**CELL, "offsets": [0.3, 0.6]}                  # same data and options, more guesses: one context
    options = {**CELL, "identification": {"max_iterations": 4}}   # other options: another context
    p = plan({"a": other, "b": options})
    batches = list(identify_batches(p, 10).values())
    assert sorted(map(len, batches)) == [3, 6]
    for batch in batches:
        specs = [p.jobs["identify"][path] for path in batch]
        assert all({**s, "initial": None} == {**specs[0], "initial": None} for s in specs)
        assert len({str(s["initial"]) for s in specs}) == len(specs)


def test_the_base_of_a_finite_sensitivity_runs_alone():
    p = plan({"cell": {**CELL, "sensitivity": "both"}})
    base = next(iter(p.jobs["sensitivity"].values()))["identification"]
    batched = [path for batch in identify_batches(p, 10).values() for path in batch]
    assert base not in batched and len(batched) == 2


def test_the_batch_size_is_validated():
    with pytest.raises(ConfigError, match="identify_batch"):
        plan({"cell": CELL}, identify_batch=0)
    assert validate_config({"scenes": {"cell": CELL}}, SCHEMA)["identify_batch"] == 10


def snakemake(workdir, batch, *args):
    (workdir / "config.yaml").write_text(yaml.safe_dump({"report": {"enabled": False}, "identify_batch": batch,
                                                         "scenes": {"cell": CELL}}))
    return subprocess.run([SNAKEMAKE, "-s", str(ROOT / "Snakefile"), "-d", str(workdir), "--cores", "2", *args],
                          capture_output=True, text=True)


def test_a_batch_writes_what_single_jobs_write_and_either_reuses_the_others_files(tmp_path):
    alone, batched = tmp_path / "alone", tmp_path / "batched"
    for workdir, batch in ((alone, 1), (batched, 3)):
        workdir.mkdir()
        out = snakemake(workdir, batch)
        assert out.returncode == 0, out.stderr[-3000:]
    assert not list((alone / "results/benchmarks/identify").glob("batch-*.tsv"))
    assert len(list((batched / "results/benchmarks/identify").glob("batch-coarse-*.tsv"))) == 1
    logs = sorted(p.stem for p in (batched / "results/logs/identify").glob("*.log"))
    assert logs == sorted(p.stem for p in (batched / "results/identify").glob("*.nc")) and len(logs) == 3
    indices = []
    for key in logs:
        text = (batched / "results/logs/identify" / f"{key}.log").read_text()
        assert "newton it=" in text and "fit verdict" in text
        job = JOB_LINE.search(text.splitlines()[0])
        assert job.group(2) == "3" and job.group(3).startswith("identify_batch_"), text.splitlines()[0]
        indices.append(int(job.group(1)))
    assert sorted(indices) == [1, 2, 3]
    # job seconds: a batch's shares sum to its benchmark; alone, each its own benchmark
    batch_seconds = benchmark_seconds(next((batched / "results/benchmarks/identify").glob("batch-*.tsv")))
    shares = identification_seconds(batched / "results")
    assert sorted(shares) == logs and all(s > 0 for s in shares.values())
    assert sum(shares.values()) == pytest.approx(batch_seconds, rel=1e-12)
    single = identification_seconds(alone / "results")
    assert single == {k: benchmark_seconds(alone / f"results/benchmarks/identify/{k}.tsv") for k in logs}
    result = compare_results(alone / "results", batched / "results")
    assert result.identical and result.pairs >= 3 + 3, result.differences     # mesh, solve, measure, 3 identifications
    # files made by single jobs are not rerun by a batch, nor the other way round
    for workdir, batch in ((alone, 3), (batched, 1)):
        out = snakemake(workdir, batch, "-n")
        assert out.returncode == 0 and "Nothing to be done" in out.stdout + out.stderr, out.stdout[-2000:]


def _write_run(folder, logs, benchmarks):
    """A results folder with identify logs ``{stem: [lines]}`` and benchmark files ``{stem: seconds}``."""
    (folder / "logs/identify").mkdir(parents=True)
    (folder / "benchmarks/identify").mkdir(parents=True)
    for stem, lines in logs.items():
        (folder / f"logs/identify/{stem}.log").write_text("\n".join(lines) + "\n")
    for stem, seconds in benchmarks.items():
        (folder / f"benchmarks/identify/{stem}.tsv").write_text(f"s\th:m:s\n{seconds}\t0:00:00\n")


def _log(start, end, job, index=1, count=2):
    stamp = lambda t: f"2026-12-03 12:00:{t:06.3f}".replace(".", ",")   # logging's format: 12:00:02,000
    return [f"{stamp(start)} INFO breastcore.stages.identify: identification {index} of {count} in job {job}",
            f"{stamp(end)} INFO breastcore.stages.identify: fit verdict consistent"]


def test_job_seconds_split_a_batch_by_log_span_and_ignore_tracebacks_and_stale_files(tmp_path):
    failed = _log(10.0, 14.0, "identify_batch_abc", 2) + ["Traceback (most recent call last):", '  File "x.py"']
    _write_run(tmp_path, {"a": _log(0.0, 2.0, "identify_batch_abc", 1), "z": failed,
                          "c": _log(0.0, 5.0, "identify", 1, 1), "old": ["2026-11-01 10:00:00,000 DEBUG no job line"]},
               # "z" was made alone before its batch remade it: its own file (read after the batch's) is stale
               {"batch-coarse-abc": 12.0, "z": 99.0, "c": 7.5, "old": 3.0, "batch-coarse-gone": 1.0})
    seconds = identification_seconds(tmp_path)
    assert seconds == pytest.approx({"a": 4.0, "z": 8.0, "c": 7.5, "old": 3.0})


def test_job_seconds_of_a_batch_without_time_spans_are_equal_shares(tmp_path):
    _write_run(tmp_path, {"a": _log(1.0, 1.0, "identify_batch_k"), "b": _log(1.0, 1.0, "identify_batch_k", 2)},
               {"batch-coarse-k": 6.0})
    assert identification_seconds(tmp_path) == {"a": 3.0, "b": 3.0}
