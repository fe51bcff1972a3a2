"""make run (breastcore.pipeline.run): a killed run is recovered, never a live one (issue #19)."""

import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import xarray as xr
import yaml

from breastcore.pipeline.run import (
    _option_values,
    is_snakemake,
    lock_files,
    recover,
    snakemake_directory,
    snakemake_processes,
)

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")

# A patient on the medium mesh: its identification takes seconds, long enough to be
# killed in the middle of it.
PATIENT = {"report": {"enabled": True}, "scenes": {"alice": {
    "kind": "patient", "mesh": "medium", "identification": {"max_iterations": 15}, "sensitivity": "none",
    "postures": {"standing": {"volume": 660, "area": 344, "height": 110, "frontal_depth": 51, "back_depth": 45},
                 "bent45": {"volume": 1230, "area": 296, "height": 89, "frontal_depth": 68, "back_depth": 67},
                 "fours": {"volume": 1014, "area": 238, "height": 105, "frontal_depth": 68, "back_depth": 68}}}}}


def make_run_command(*args):
    """The command `make run ARGS=...` runs, as make prints it, with this test's Python.

    The Makefile's venv may not be the one running the tests, so its `.installed` and `.warm`
    targets are taken as up to date and its python replaced by this one.
    """
    if shutil.which("make") is None:
        pytest.skip("no make")
    binary = Path(sys.executable).parent
    out = subprocess.run(["make", "-s", "-n", "-C", str(ROOT), "-o", f"{binary}/.installed", "-o", f"{binary}/.warm",
                          f"BIN={binary}",
                          "run", f"ARGS={shlex.join(args)}"], capture_output=True, text=True, check=True)
    command = shlex.split(out.stdout.strip())
    assert command[:4] == [f"{binary}/python", "-m", "breastcore.pipeline.run", "--cores"], out.stdout
    return [sys.executable, *command[1:]]


def test_option_values_read_snakemake_command_lines():
    assert _option_values(["-d", "x", "--cores", "2"], "--directory", "-d", "--dir") == ["x"]
    assert _option_values(["-dx"], "--directory", "-d") == ["x"]
    assert _option_values(["--dir=y"], "--directory", "-d", "--dir") == ["y"]
    assert _option_values(["--dir", "y", "-n"], "--directory", "-d", "--dir") == ["y"]
    assert _option_values(["--dry-run", "-n"], "--directory", "-d", "--dir") == []
    files = ["--configfile", "a", "b", "--config", "x=1", "--configfiles=c", "-n", "--configfiles", "d"]
    assert _option_values(files, "--configfiles", shortest="--configfile", many=True) == ["a", "b", "c", "d"]
    assert _option_values(["--config", "x=1"], "--configfiles", shortest="--configfile", many=True) == []
    assert snakemake_directory(["snakemake", "-d", "sub"], "/w") == Path("/w/sub").resolve()
    assert snakemake_directory(["snakemake", "-n"], "/w") == Path("/w").resolve()


@pytest.mark.parametrize("argv, expected", [
    (["/v/bin/python", "/v/bin/snakemake", "--cores", "2"], True),         # the console script
    (["snakemake", "-n"], True),
    (["/v/bin/python", "-m", "snakemake", "--target-jobs", "x"], True),    # a job Snakemake spawns
    (["/v/bin/python", "/w/.snakemake/scripts/tmpab12.identify.py"], True),  # a script: job
    (["/v/bin/python", "-m", "breastcore.pipeline.run", "--cores", "2"], False),
    (["/v/bin/python", "/v/bin/pytest", "tests/pipeline/test_workflow.py", "-k", "snakemake"], False),
    (["make", "run"], False)])
def test_is_snakemake(argv, expected):
    assert is_snakemake(argv) is expected


def _fake_proc(tmp_path, processes):
    """A /proc with a `self` and, per (pid, argv, cwd[, parent pid]), its cmdline, cwd link and stat
    (parent 1, init, unless given; None: no stat, as for a process that cannot be read)."""
    proc = tmp_path / "proc"
    (proc / "self").mkdir(parents=True)
    for pid, argv, cwd, *parent in processes:
        (proc / str(pid)).mkdir()
        (proc / str(pid) / "cmdline").write_bytes(b"".join(w.encode() + b"\0" for w in argv))
        (proc / str(pid) / "cwd").symlink_to(cwd)
        parent = parent[0] if parent else 1
        if parent is not None:                       # the name is in brackets, and may hold them
            (proc / str(pid) / "stat").write_text(f"{pid} (py) thon) S {parent} {pid} {pid} 0 -1 4194304\n")
    return proc


def _locked(workdir):
    locks = workdir / ".snakemake" / "locks"
    locks.mkdir(parents=True)
    (locks / "0.input.lock").write_text("results/mesh/coarse.nc\n")
    (locks / "0.output.lock").write_text("results/identify/x.nc\n")
    return workdir


def _no_wait(seconds):
    raise AssertionError("recover() waited: no orphaned job here")


@pytest.mark.parametrize("case, live", [
    ("none", False),
    ("run here", True), ("run from elsewhere with -d here", True), ("job of a live run here", True),
    ("job of a live run's job here", True), ("job whose parent cannot be read", True),
    ("run in another folder", False), ("run from here with -d elsewhere", True)])
def test_a_lock_is_removed_only_without_a_live_snakemake_in_its_folder(tmp_path, case, live):
    workdir = _locked(tmp_path / "work")
    other = tmp_path / "other"
    other.mkdir()
    python = "/v/bin/python"
    script = [python, f"{workdir}/.snakemake/scripts/tmpab.identify.py"]
    processes = {
        "none": [(10, ["make", "run"], workdir)],
        "run here": [(11, [python, "/v/bin/snakemake", "--cores", "2"], workdir)],
        "run from elsewhere with -d here": [(12, ["snakemake", "-d", str(workdir)], other)],
        "job of a live run here": [(13, [python, "/v/bin/snakemake", "--cores", "2"], workdir, 5),
                                   (16, script, workdir, 13)],
        "job of a live run's job here": [(17, [python, "/v/bin/snakemake", "-d", str(workdir)], other, 1),
                                         (18, [python, "-m", "snakemake", "--target-jobs", "x"], workdir, 17),
                                         (19, script, workdir, 18)],
        "job whose parent cannot be read": [(20, script, workdir, None)],
        "run in another folder": [(14, ["snakemake", "--cores", "2"], other)],
        # before Snakemake has changed to its -d folder, its folder is still this one
        "run from here with -d elsewhere": [(15, ["snakemake", "-d", str(other)], workdir)]}[case]
    proc = _fake_proc(tmp_path, processes)
    extra, note = recover(workdir, proc=str(proc), sleep=_no_wait)
    if live:
        assert extra == [] and len(lock_files(workdir)) == 2
        assert f"Snakemake process {processes[0][0]} works in {workdir}" in note and "left alone" in note
    else:
        assert extra == ["--rerun-incomplete"] and lock_files(workdir) == []
        assert "removed the lock a killed Snakemake run left" in note


@pytest.mark.parametrize("parents", [[], [(30, ["bash"], "/", 1)], [(31, ["systemd", "--user"], "/", 1)]],
                         ids=["init", "a shell", "a subreaper"])
def test_a_job_whose_snakemake_was_killed_is_waited_for_then_the_lock_removed(tmp_path, parents):
    """kill -9 of Snakemake's pid alone (not its process group) leaves its jobs running, handed to
    init or a subreaper: no run holds the lock any more, but the job still writes the output that
    the rerun would write. It is named and waited for; then the lock is removed, its job rerun."""
    workdir = _locked(tmp_path / "work")
    parent = parents[0][0] if parents else 1
    job = (13, ["/v/bin/python", f"{workdir}/.snakemake/scripts/tmpab.identify.py"], workdir, parent)
    proc = _fake_proc(tmp_path, [*parents, job])
    said, waits = [], []

    def sleep(seconds):
        waits.append(seconds)
        assert len(lock_files(workdir)) == 2                 # nothing is removed while the job runs
        if len(waits) == 3:                                  # the job ends
            shutil.rmtree(proc / "13")

    extra, note = recover(workdir, proc=str(proc), sleep=sleep, say=said.append)
    assert len(waits) == 3 and len(said) == 1, said          # said once, not at every look
    assert said[0].startswith(f"breastcore.pipeline.run: job process 13 of a killed Snakemake run still works in "
                              f"{workdir}") and "waiting for it to end (or kill 13)" in said[0]
    assert extra == ["--rerun-incomplete"] and lock_files(workdir) == []
    assert "removed the lock a killed Snakemake run left" in note


def test_a_run_started_while_an_orphaned_job_is_waited_for_keeps_its_lock(tmp_path):
    workdir = _locked(tmp_path / "work")
    proc = _fake_proc(tmp_path, [(13, ["/v/bin/python", f"{workdir}/.snakemake/scripts/tmpab.identify.py"],
                                  workdir)])

    def sleep(seconds):                                      # meanwhile, someone runs snakemake here
        shutil.rmtree(proc / "13")
        (proc / "40").mkdir()
        (proc / "40" / "cmdline").write_bytes(b"snakemake\0--cores\0" + b"2\0")
        (proc / "40" / "cwd").symlink_to(workdir)

    extra, note = recover(workdir, proc=str(proc), sleep=sleep, say=lambda line: None)
    assert extra == [] and len(lock_files(workdir)) == 2
    assert f"Snakemake process 40 works in {workdir}" in note


def test_without_a_process_list_the_lock_is_left_and_the_manual_commands_are_named(tmp_path):
    workdir = _locked(tmp_path / "work")
    extra, note = recover(workdir, proc=str(tmp_path / "no-proc"))
    assert extra == [] and len(lock_files(workdir)) == 2
    assert "snakemake --unlock" in note and "--rerun-incomplete" in note
    extra, note = recover(tmp_path, proc=str(tmp_path / "no-proc"))    # no lock: nothing to say
    assert extra == ["--rerun-incomplete"] and note is None


@pytest.mark.parametrize("cores, shown", [("4", "--cores 4"), (None, "--cores N")])
def test_the_manual_commands_name_the_runs_own_cores(tmp_path, cores, shown):
    """They said --cores 2 whatever the run was given."""
    workdir = _locked(tmp_path / "work")
    extra, note = recover(workdir, proc=str(tmp_path / "no-proc"), cores=cores)
    assert extra == [] and note.endswith(f"then snakemake {shown} --rerun-incomplete"), note


def _wait_for(condition, process, timeout=300):
    start = time.monotonic()
    while not condition():
        assert process.poll() is None, "the run ended before it could be killed"
        assert time.monotonic() - start < timeout, "timed out"
        time.sleep(0.05)


def test_make_run_finishes_a_run_killed_during_identification(tmp_path):
    """kill -9 of a real run's process group while an identification runs, then the
    make-run mechanism again: it finishes with no manual step, and every dataset reads.
    Without it, Snakemake stops on the lock, and (after --unlock) on the incomplete file."""
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(PATIENT))
    command = make_run_command("-s", str(ROOT / "Snakefile"))
    with open(tmp_path / "first.log", "w") as log:
        run = subprocess.Popen(command, cwd=tmp_path, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        logs = tmp_path / "results/logs/identify"
        _wait_for(lambda: logs.is_dir() and any(logs.iterdir()), run)
        # Under the live run: it is seen, and its lock is left alone.
        live = snakemake_processes(tmp_path)
        assert any(pid == run.pid for pid, _ in live), live
        locks = lock_files(tmp_path)
        extra, note = recover(tmp_path)
        assert locks and extra == [] and "left alone" in note and lock_files(tmp_path) == locks
    finally:
        os.killpg(run.pid, signal.SIGKILL)
        run.wait()
    time.sleep(0.5)                                               # the kernel reaps the group
    assert snakemake_processes(tmp_path) == []
    key = next(logs.iterdir()).stem
    assert not (tmp_path / f"results/identify/{key}.nc").exists()   # it was killed before writing
    # What a job killed in the middle of a write leaves where it does not write atomically
    # (a PNG, a CSV): a part of the file. Snakemake marked it incomplete.
    (tmp_path / f"results/identify/{key}.nc").write_bytes(b"CDF\x01 half")

    plain = subprocess.run([SNAKEMAKE, "-s", str(ROOT / "Snakefile"), "--cores", "2"], cwd=tmp_path,
                           capture_output=True, text=True)
    assert plain.returncode == 1 and "IncompleteFilesException" in plain.stderr, plain.stderr[-2000:]
    assert lock_files(tmp_path)

    again = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=1200)
    assert again.returncode == 0, again.stderr[-3000:]
    assert "removed the lock a killed Snakemake run left" in again.stderr
    assert lock_files(tmp_path) == []
    datasets = sorted((tmp_path / "results").rglob("*.nc"))
    assert f"results/identify/{key}.nc" in {p.relative_to(tmp_path).as_posix() for p in datasets}
    for path in datasets:
        with xr.open_dataset(path) as ds:
            ds.load()
    dry = subprocess.run([SNAKEMAKE, "-s", str(ROOT / "Snakefile"), "-n"], cwd=tmp_path, capture_output=True,
                         text=True)
    assert dry.returncode == 0 and "Nothing to be done" in dry.stdout + dry.stderr, dry.stdout + dry.stderr


def test_make_run_names_the_file_and_line_of_a_malformed_configfile(tmp_path):
    """Snakemake reads a --configfile before the Snakefile, and says only "Config file is
    not valid JSON or YAML"; the make-run mechanism reads it first."""
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(PATIENT))
    (tmp_path / "copy.yaml").write_text("scenes:\n  alice:\n\tkind: patient\n")
    out = subprocess.run(make_run_command("-s", str(ROOT / "Snakefile"), "-n", "--configfile", "copy.yaml"),
                         cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 1
    assert out.stderr.splitlines() == [
        "ConfigError: config file copy.yaml, line 3, column 1: a tab, which YAML does not allow as indentation "
        "(indent with spaces)"]
