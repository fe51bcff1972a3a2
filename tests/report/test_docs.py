"""The README states every default with its source, and the quick start is two commands."""

import re
from pathlib import Path

from breastcore.model.parameters import PARAMETER_INFO

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


def test_readme_lists_every_parameter_default_and_source():
    """Each parameter's row: its default, unit and source, as PARAMETER_INFO gives them."""
    rows = {m.group(1): m for m in re.finditer(r"^\| `(\w+)`: [^|]*\| ([^|]+) \| ([^|]+) \| [^|]+ \| (?:yes|no) \| ([^|]+) \|$",
                                               README, re.M)}
    for name, info in PARAMETER_INFO.items():
        assert name in rows, name
        row = rows[name]
        assert float(row.group(2)) == info.default, name
        assert row.group(3).strip() == info.units, name
        assert row.group(4).strip() == info.source, name


def test_readme_defaults_are_generated_from_the_code():
    """The README's tables of defaults are the code's: rewrite them with
    ``python -m breastcore.report.readme_tables README.md`` after changing a default."""
    from breastcore.report.readme_tables import defaults_markdown
    assert defaults_markdown() in README


def test_the_generated_tables_follow_a_changed_default(monkeypatch):
    """The generator reads the dataclasses, not a copy: a changed default shows in its table."""
    import dataclasses

    from breastcore.forward.options import SolverOptions
    from breastcore.report import readme_tables
    changed = dataclasses.make_dataclass("SolverOptions", [("rtol", float, dataclasses.field(default=3e-9))])
    changed.__doc__ = SolverOptions.__doc__
    assert "| `rtol` | 3e-09 | Converged when" in readme_tables.options_table(changed)
    text = "a\n" + readme_tables.BEGIN + "\nstale\n" + readme_tables.END + "\nb\n"
    assert readme_tables.replace_block(text) == "a\n" + readme_tables.defaults_markdown() + "\nb\n"


def test_quick_start_is_two_commands_and_ci_runs_the_test_command():
    block = README.split("## Quick start")[1].split("```sh")[1].split("```")[0]
    commands = [line.split("#")[0].strip() for line in block.strip().splitlines()]
    assert commands == ["make run", "make test"]
    assert "make test" in (ROOT / ".ci/run").read_text()
