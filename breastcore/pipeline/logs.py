"""Logging of workflow jobs (one line per Newton and per identification iteration), and their benchmark files."""

from __future__ import annotations

import contextlib
import logging
from pathlib import Path


def benchmark_seconds(path) -> float | None:
    """Wall seconds of a job from its Snakemake ``benchmark:`` file (the first data row), or None if absent."""
    path = Path(path)
    if not path.exists():
        return None
    return float(path.read_text().splitlines()[1].split()[0])


@contextlib.contextmanager
def log_to(path):
    """Send breastcore's log (Newton iterations at DEBUG included) to ``path`` for the block."""
    handler = logging.FileHandler(path, mode="w")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger("breastcore")
    root.addHandler(handler)
    level = root.level
    root.setLevel(logging.DEBUG)
    try:
        yield
    except Exception:
        root.exception("job failed")
        raise
    finally:
        root.removeHandler(handler)
        root.setLevel(level)
        handler.close()
