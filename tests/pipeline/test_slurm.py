"""The workflow on a real SLURM (issue #22): a single-node cluster on this machine (Debian's
slurm-wlm: slurmctld and slurmd on localhost, munge for authentication) runs a small scene
through Snakemake's SLURM executor plugin, and its datasets must equal a local run's.

Run by ``make test-slurm`` (which installs slurm-wlm, munge and the plugin), not by the unit
suite: it needs root, writes ``/etc/slurm/slurm.conf`` (only where none exists, or one this
test wrote) and starts and stops the daemons. Jobs inside an allocation call ``srun``, which
reads the default configuration path, not ``SLURM_CONF``.
"""

import os
import re
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
import yaml

from breastcore.report.compare import compare_results, render

from test_workflow import ROOT, SNAKEMAKE, TINY, snakemake

pytestmark = pytest.mark.slurm

SLURM_CONF = Path("/etc/slurm/slurm.conf")
MARKER = "# written by breastcore tests/pipeline/test_slurm.py"
#: The patient and the forward scene of the unit suite's tiny workflow (6 jobs and `all`, no report).
SCENE = {"report": {"enabled": False},
         "scenes": {"alice": {**TINY["scenes"]["alice"], "sensitivity": "none"}, "fwd": TINY["scenes"]["fwd"]}}


def _conf(state: Path, node: str) -> str:
    """The cluster's configuration; ``node`` is ``slurmd -C``'s line for this machine (its real CPUs
    and memory: a node declared bigger than it is never becomes idle)."""
    host = re.match(r"NodeName=(\S+)", node).group(1)
    return f"""{MARKER}
ClusterName=breastcore-test
SlurmctldHost={host}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
# finished jobs stay in squeue for an hour: the plugin's status command here is squeue (no sacct
# without an accounting database)
MinJobAge=3600
SlurmctldPidFile={state}/slurmctld.pid
SlurmdPidFile={state}/slurmd.pid
SlurmdSpoolDir={state}/spool
StateSaveLocation={state}/state
SlurmctldLogFile={state}/slurmctld.log
SlurmdLogFile={state}/slurmd.log
{node} State=UNKNOWN
PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP
"""


def _stop(pid_file: Path):
    """Stop the daemon whose pid ``pid_file`` holds (the one this test started, nothing else)."""
    try:
        os.kill(int(pid_file.read_text().split()[0]), signal.SIGTERM)
    except (OSError, ValueError, IndexError):
        pass


def _munge_works() -> bool:
    return subprocess.run(["munge", "-n"], capture_output=True).returncode == 0


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    for program in ("slurmctld", "slurmd", "munged", "munge", "sbatch", "squeue", "sinfo", "scontrol"):
        assert shutil.which(program), f"{program} not found: `make test-slurm` installs slurm-wlm and munge"
    assert SLURM_CONF.exists() is False or MARKER in SLURM_CONF.read_text(), \
        f"{SLURM_CONF} exists and is not this test's: refusing to replace a real cluster's configuration"
    state = tmp_path_factory.mktemp("slurm")
    (state / "spool").mkdir()
    (state / "state").mkdir()
    node = subprocess.run(["slurmd", "-C"], capture_output=True, text=True, check=True).stdout.splitlines()[0]
    munge_pid = Path("/run/munge/munged.pid")
    started_munge = False
    try:
        SLURM_CONF.parent.mkdir(parents=True, exist_ok=True)
        SLURM_CONF.write_text(_conf(state, node))
        if not _munge_works():
            munge_pid.parent.mkdir(parents=True, exist_ok=True)
            shutil.chown(munge_pid.parent, "munge", "munge")
            subprocess.run(["runuser", "-u", "munge", "--", "munged"], check=True)
            started_munge = True
        subprocess.run(["slurmctld"], check=True)
        subprocess.run(["slurmd"], check=True)
        for _ in range(60):
            info = subprocess.run(["sinfo", "-h", "-o", "%T"], capture_output=True, text=True)
            if info.stdout.strip() == "idle":
                break
            time.sleep(1)
        else:
            pytest.fail(f"the node never became idle: {info.stdout} {info.stderr} "
                        f"{(state / 'slurmctld.log').read_text()[-2000:]}")
        yield state
    finally:
        subprocess.run(["scontrol", "shutdown"], capture_output=True)
        _stop(state / "slurmctld.pid")
        _stop(state / "slurmd.pid")
        if started_munge:
            _stop(munge_pid)
        SLURM_CONF.unlink(missing_ok=True)


def test_a_scene_through_the_slurm_executor_equals_a_local_run(cluster, tmp_path):
    local, remote = tmp_path / "local", tmp_path / "slurm"
    for folder in (local, remote):
        folder.mkdir()
        (folder / "config.yaml").write_text(yaml.safe_dump(SCENE))
    out = snakemake(local)
    assert out.returncode == 0, out.stderr[-3000:]
    out = subprocess.run([SNAKEMAKE, "-s", str(ROOT / "Snakefile"), "-d", str(remote),
                          "--workflow-profile", str(ROOT / "workflow/profiles/slurm"),
                          "--slurm-status-command", "squeue", "--jobs", "2",
                          "--slurm-init-seconds-before-status-checks", "1", "--seconds-between-status-checks", "2",
                          "--slurm-keep-successful-logs"],
                         capture_output=True, text=True, timeout=1800)
    assert out.returncode == 0, out.stderr[-3000:]
    submitted = list((remote / ".snakemake/slurm_logs").rglob("*.log"))
    assert len(submitted) == 6                        # every job of the scene but `all` (local) went through sbatch
    states = subprocess.run(["squeue", "-h", "-t", "all", "-o", "%T"], capture_output=True, text=True).stdout.split()
    assert states == ["COMPLETED"] * 6                # this cluster ran them all, and nothing else
    result = compare_results(local / "results", remote / "results")
    assert result.identical, render(result)
