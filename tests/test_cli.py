"""Command line: --help documents every option; bad input is one line, exit 2, no traceback."""

import subprocess
import sys

import pytest

from breastcore.parameters import PARAMETER_INFO


def run(*args):
    return subprocess.run([sys.executable, "-m", "breastcore", *args], capture_output=True, text=True)


def test_solve_help_lists_every_option_with_default():
    out = run("solve", "--help")
    assert out.returncode == 0
    text = " ".join(out.stdout.split())
    for info in PARAMETER_INFO.values():
        assert info.cli in text
        assert f"default {info.default:g}" in text
    for option in ("--mesh", "--mesh-size", "--posture", "--solver", "--out", "--rtol"):
        assert option in text


@pytest.mark.parametrize("args, option", [
    (["--H", "0.06"], "--H"),                       # H >= R
    (["--mu-breast", "-5"], "--mu-breast"),
    (["--lambda-skin", "-1"], "--lambda-skin"),
    (["--posture", "supine"], "--posture"),
    (["--posture", "tilt=120"], "--posture"),
    (["--posture", "standing=45"], "--posture"),     # a paper posture's name keeps its angle
    (["--mesh", "gigantic"], "--mesh"),
    (["--mesh-size", "-0.01"], "--mesh-size"),
    (["--R", "nan"], "--R"),
    (["--solver", "bfgs"], "--solver"),
])
def test_bad_solve_input_is_one_line_naming_the_option(tmp_path, args, option):
    out = run("solve", *args, "--out", str(tmp_path / "x.nc"))
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert option in lines[0]
    assert "Traceback" not in out.stderr
    assert not (tmp_path / "x.nc").exists()


def test_unwritable_output_path_is_rejected(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    out = run("solve", "--out", str(blocker / "x.nc"))
    assert out.returncode == 2 and "--out" in out.stderr and len(out.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("value", ["1.5", "-0.1"])
def test_bad_identify_cost_rtol_is_one_line_naming_the_option(tmp_path, value):
    (tmp_path / "m.nc").write_text("")          # exists; the option is refused before it is read
    out = run("identify", "--measurements", str(tmp_path / "m.nc"), "--cost-rtol", value,
              "--out", str(tmp_path / "x.nc"))
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "--cost-rtol" in lines[0], out.stderr
    assert not (tmp_path / "x.nc").exists()
