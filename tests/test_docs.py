"""The README states every default with its source, and the quick start is two commands."""

import re
from pathlib import Path

from breastcore.parameters import PARAMETER_INFO

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_readme_lists_every_parameter_default_and_source():
    table = {m.group(1): m for m in re.finditer(r"^\| (\w+)[^|]*\| ([^|]+) \| ([^|]+) \| ([^|]+) \|$", README, re.M)}
    for name, info in PARAMETER_INFO.items():
        assert name in table, name
        row = table[name]
        assert float(row.group(2)) == info.default, name
        assert row.group(3).strip() == info.units, name
        assert info.source.split(" ")[0] in row.group(4), name


def test_quick_start_is_two_commands_and_ci_runs_the_test_command():
    block = README.split("## Quick start")[1].split("```sh")[1].split("```")[0]
    commands = [line.split("#")[0].strip() for line in block.strip().splitlines()]
    assert commands == ["make run", "make test"]
    assert "make test" in (ROOT / ".ci/run").read_text()
