"""Plain-text tables for the scripts that print measurements: Markdown tables, a machine line.

Every number a benchmark or a run study prints goes through :func:`print_table`, so that
the tables in ``docs/benchmarks.md`` can be pasted from the output unchanged.
"""

from __future__ import annotations

import datetime
import os
import platform
import sys
from pathlib import Path

import numpy as np


def machine_line() -> str:
    """One line naming the machine, the date and the library versions."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import scipy
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (f"{datetime.date.today().isoformat()}, {os.cpu_count()} cores ({cpu}), "
            f"python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
            f"load average at start {load:.2f}")


def fmt(value, digits=3) -> str:
    """Compact number formatting for tables (``—`` for missing)."""
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "—"
    if isinstance(value, str):
        return value
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if value == 0:
        return "0"
    if abs(value) >= 1e4 or abs(value) < 1e-3:
        return f"{value:.{digits - 1}e}"
    return f"{value:.{digits}g}"


def print_table(headers, rows, title: str | None = None) -> str:
    """Print a Markdown table (and return its text)."""
    cells = [[fmt(c) for c in row] for row in rows]
    widths = [max(len(str(h)), *(len(r[i]) for r in cells)) if cells else len(str(h))
              for i, h in enumerate(headers)]
    lines = []
    if title:
        lines += [f"### {title}", ""]
    lines.append("| " + " | ".join(str(h).ljust(w) for h, w in zip(headers, widths)) + " |")
    lines.append("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in cells:
        lines.append("| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |")
    text = "\n".join(lines)
    print(text + "\n", flush=True)
    return text


def header(name: str, argv=None) -> None:
    """Print the command line and the machine line at the top of a benchmark's output."""
    argv = sys.argv if argv is None else argv
    print(f"# {name}\n\ncommand: `{' '.join(['python'] + [os.path.relpath(argv[0])] + argv[1:])}`  \n"
          f"machine: {machine_line()}\n", flush=True)
