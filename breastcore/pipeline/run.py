"""``make run``: Snakemake, after clearing what a killed run left behind.

A Snakemake run killed by SIGKILL (``kill -9``, the out-of-memory killer, a power loss)
leaves its lock files in ``.snakemake/locks`` and, marked incomplete, the outputs of the
jobs it was running. A plain ``snakemake`` then stops with LockException, and after
``snakemake --unlock`` with IncompleteFilesException until it is given
``--rerun-incomplete``. ``make run`` runs ``python -m breastcore.pipeline.run --cores 2``
instead, which

1. refuses a ``--configfile`` that is not valid YAML with one line naming its file and
   line: Snakemake reads these files before the Snakefile, and says neither;
2. looks for live Snakemake processes working in the folder: a run, or a job of one;
3. if there is none, removes the lock files a killed run left and adds
   ``--rerun-incomplete``; if there is a run (or a job of a live run), leaves its lock and
   its unfinished outputs alone and says so (Snakemake then refuses to run if the two runs'
   files overlap); a job whose Snakemake is gone (``kill -9`` of Snakemake's process
   alone leaves its jobs running, orphaned) holds no lock but still writes the output that
   the rerun would write: it is named, waited for, and then treated as above;
4. replaces itself with ``snakemake`` and the same arguments.

Processes are read from ``/proc`` (Linux). Where there is none, a lock is left in place
and the manual commands are printed.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
import time
from pathlib import Path

from breastcore.pipeline.config_files import ConfigError, check_config_files

#: Snakemake's lock files (``snakemake/persistence/file.py`` reads exactly these names).
LOCK_NAME = re.compile(r"[0-9]+\.(input|output)\.lock")
PROG = "breastcore.pipeline.run"
#: In the path of a ``script:`` job: ``python <folder>/.snakemake/scripts/tmpXXXX.name.py``.
SCRIPTS = f"{os.sep}.snakemake{os.sep}scripts{os.sep}"


def _option_values(argv, long, short=None, shortest=None, many=False):
    """Values of one option in a command line: ``--directory DIR``, ``--directory=DIR``, ``-d DIR``, ``-dDIR``.

    Parameters
    ----------
    argv : list of str
        The command line.
    long, short : str
        The option's names (``"--directory"``, ``"-d"``).
    shortest : str, optional
        The shortest abbreviation of ``long`` to accept, as argparse accepts any
        unambiguous one (``--dir``); default: ``long`` only.
    many : bool
        The option takes every following word up to the next option, as Snakemake's
        ``--configfile A B`` does.
    """
    def is_long(name):
        return name.startswith(shortest or long) and long.startswith(name)

    values, i = [], 0
    while i < len(argv):
        word = argv[i]
        i += 1
        if word.startswith("--") and is_long(word.split("=", 1)[0]):
            if "=" in word:
                values.append(word.split("=", 1)[1])
                continue
        elif short and word.startswith(short) and not word.startswith("--"):
            if len(word) > len(short):
                values.append(word[len(short):])
                continue
        else:
            continue
        while i < len(argv) and not argv[i].startswith("-"):
            values.append(argv[i])
            i += 1
            if not many:
                break
    return values


def snakemake_directory(argv, cwd) -> Path:
    """The working folder of a Snakemake command line: its ``-d``/``--directory``, else ``cwd``."""
    values = _option_values(list(argv), "--directory", "-d", shortest="--dir")
    return (Path(cwd) / values[-1]).resolve() if values else Path(cwd).resolve()


def is_snakemake(argv) -> bool:
    """Whether a process's command line is Snakemake's or one of its jobs'.

    ``snakemake ...`` (the console script: ``python .../snakemake ...``), ``python -m
    snakemake ...`` (how Snakemake spawns some jobs), and a ``script:`` job, which runs
    ``python <folder>/.snakemake/scripts/tmpXXXX.name.py``.
    """
    argv = list(argv)
    if any(Path(word).name == "snakemake" for word in argv[:2]):
        return True
    if any(argv[i] == "-m" and argv[i + 1] == "snakemake" for i in range(1, min(len(argv) - 1, 4))):
        return True
    return any(SCRIPTS in word for word in argv[1:3])


def is_job(argv) -> bool:
    """Whether a Snakemake command line (:func:`is_snakemake`) is a job's rather than a run's.

    A ``script:`` job (``python <folder>/.snakemake/scripts/tmpXXXX.name.py``), or a job
    Snakemake spawns as ``python -m snakemake --target-jobs ...``.
    """
    argv = list(argv)
    return any(SCRIPTS in word for word in argv[1:3]) or "--target-jobs" in argv


def _parent(proc, pid):
    """The parent pid of ``pid`` from ``proc/PID/stat``, or None if it cannot be read."""
    try:
        stat = (Path(proc) / str(pid) / "stat").read_text()
        return int(stat[stat.rindex(")") + 2:].split()[1])     # after "pid (comm) state"; comm may hold ")"
    except (OSError, ValueError, IndexError):
        return None


def _command(proc, pid):
    """The command line of ``pid`` from ``proc/PID/cmdline``, or None if it cannot be read."""
    try:
        return [w.decode(errors="replace") for w in (Path(proc) / str(pid) / "cmdline").read_bytes().split(b"\0")[:-1]]
    except OSError:
        return None


def orphaned(pid, argv, proc="/proc") -> bool:
    """Whether the Snakemake process ``pid`` is a job whose Snakemake run is gone.

    A job of a live run has the run among its ancestors; one of a run killed alone (``kill
    -9`` of its pid, not of its process group) has been handed to init or a subreaper. Where
    an ancestor cannot be read, the job counts as a live run's: its lock is left alone.
    """
    if not is_job(argv):
        return False
    seen = {pid}
    parent = _parent(proc, pid)
    while parent is not None and parent > 1 and parent not in seen:
        seen.add(parent)
        command = _command(proc, parent)
        if command is None:
            return False
        if is_snakemake(command) and not is_job(command):
            return False
        parent = _parent(proc, parent)
    return parent is not None


def lock_files(workdir) -> list[Path]:
    """The lock files of Snakemake's default (file) persistence in ``workdir``."""
    folder = Path(workdir) / ".snakemake" / "locks"
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if LOCK_NAME.fullmatch(p.name) and p.is_file())


def snakemake_processes(workdir, proc="/proc"):
    """Live Snakemake processes (runs and their jobs) working in ``workdir``.

    Parameters
    ----------
    workdir : str or Path
        The folder whose ``.snakemake`` is in question.
    proc : str
        The process file system.

    Returns
    -------
    list of (int, str) or None
        (pid, command line) of each; None where processes cannot be listed (no ``proc``).
        A process of another user whose folder cannot be read counts when it owns one of
        the lock files: only then can it hold the lock.
    """
    root = Path(proc)
    if not (root / "self").exists():
        return None
    workdir = Path(workdir).resolve()
    owners = {p.stat().st_uid for p in lock_files(workdir)}
    found = []
    for entry in root.iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        argv = _command(root, entry.name)
        if argv is None:                                  # ended meanwhile
            continue
        try:
            uid = entry.stat().st_uid
        except OSError:
            continue
        if not argv or not is_snakemake(argv):            # a zombie has no command line, and holds nothing
            continue
        try:
            cwd = os.readlink(entry / "cwd")
        except PermissionError:
            cwd = None
        except OSError:
            continue
        if cwd is not None:
            here = snakemake_directory(argv, cwd) == workdir or Path(cwd).resolve() == workdir
        else:
            absolute = [Path(d) for d in _option_values(argv, "--directory", "-d", "--dir") if os.path.isabs(d)]
            here = (absolute and absolute[-1].resolve() == workdir) or uid in owners
        if here:
            found.append((int(entry.name), " ".join(argv)))
    return sorted(found)


#: Seconds between two looks at an orphaned job that :func:`recover` waits for.
POLL_SECONDS = 5.0


def recover(workdir, proc="/proc", sleep=time.sleep, say=None, cores=None):
    """Clear a killed run's lock in ``workdir`` when no Snakemake process works there.

    Parameters
    ----------
    workdir : str or Path
        Snakemake's working folder.
    proc : str
        The process file system.
    sleep : callable
        ``sleep(seconds)`` between two looks at an orphaned job (:func:`orphaned`), which
        is waited for: it still writes an output that the rerun would write.
    say : callable, optional
        ``say(line)`` tells the user what is waited for (default: a line on stderr).
    cores : str, optional
        The run's ``--cores``, for the manual commands (``N`` where not given).

    Returns
    -------
    extra : list of str
        Arguments to add to Snakemake's: ``--rerun-incomplete`` when no Snakemake
        process works in ``workdir``, else none.
    note : str or None
        One line for the user when something was done, or left undone on purpose.
    """
    workdir = Path(workdir).resolve()
    locks = lock_files(workdir)
    live = snakemake_processes(workdir, proc)
    said = set()
    while live and all(orphaned(pid, _command(proc, pid) or [], proc) for pid, command in live):
        for pid, command in live:
            if pid not in said:
                shown = command if len(command) <= 100 else command[:99] + "…"
                (say or _stderr)(f"{PROG}: job process {pid} of a killed Snakemake run still works in {workdir} "
                                 f"({shown}): waiting for it to end (or kill {pid}); its job is then rerun")
                said.add(pid)
        sleep(POLL_SECONDS)
        live = snakemake_processes(workdir, proc)
    if live:
        pid, command = next(((p, c) for p, c in live if not orphaned(p, _command(proc, p) or [], proc)), live[0])
        command = command if len(command) <= 100 else command[:99] + "…"
        return [], (f"{PROG}: Snakemake process {pid} works in {workdir} ({command}): its lock and "
                    f"unfinished outputs are left alone")
    if live is None and locks:
        return [], (f"{PROG}: cannot list processes here (no {proc}), so the lock in {workdir}/.snakemake/locks "
                    f"is left alone; if no Snakemake runs there: snakemake --unlock, then "
                    f"snakemake --cores {cores or 'N'} --rerun-incomplete")
    # No live process: the lock files are a killed run's. Only those listed before the
    # process scan are removed, so a run started since keeps its own (Snakemake numbers a
    # new run's files past the existing ones). Without /proc but also without lock files,
    # no run holds a lock here, so none is writing the outputs marked incomplete.
    for path in locks:
        try:
            path.unlink()
        except FileNotFoundError:                         # removed meanwhile
            pass
    note = (f"{PROG}: removed the lock a killed Snakemake run left in {workdir}/.snakemake/locks "
            f"(no Snakemake process works there); its unfinished jobs are rerun") if locks else None
    return ["--rerun-incomplete"], note


def _stderr(line):
    print(line, file=sys.stderr, flush=True)


def _snakemake_command():
    """The ``snakemake`` beside this Python (the venv's), else ``python -m snakemake``."""
    script = shutil.which("snakemake", path=os.path.dirname(sys.executable))
    return [script] if script else [sys.executable, "-m", "snakemake"]


def main(argv=None) -> int:
    """Check the ``--configfile`` files, recover from a killed run, then exec Snakemake.

    Parameters
    ----------
    argv : list of str, optional
        Snakemake's arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        1 for a config file that is not valid YAML (one line on stderr); otherwise the
        process becomes Snakemake, whose exit status is the run's.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    # --configfile and --configfiles; a shorter abbreviation is ambiguous, and --config
    # gives KEY=VALUE pairs
    configfiles = [p for p in _option_values(argv, "--configfiles", shortest="--configfile", many=True)
                   if os.path.isfile(p)]
    try:
        check_config_files(configfiles)
    except ConfigError as err:
        print(f"ConfigError: {err}", file=sys.stderr)
        return 1
    cores = _option_values(argv, "--cores", "-c")
    extra, note = recover(snakemake_directory(argv, os.getcwd()), cores=cores[-1] if cores else None)
    if note:
        print(note, file=sys.stderr, flush=True)
    if any(word in ("--rerun-incomplete", "--ri") for word in argv):
        extra = []
    command = _snakemake_command()
    os.execv(command[0], [*command, *argv, *extra])
    return 0  # not reached: execv does not return


if __name__ == "__main__":
    sys.exit(main())
