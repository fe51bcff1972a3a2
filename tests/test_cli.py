"""Command line: --help documents every option; bad input is one line, exit 2, no traceback."""

import subprocess
import sys
from pathlib import Path

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


def test_list_names_the_scenes_each_dataset_serves(tmp_path, capsys):
    import xarray as xr

    from breastcore.cli import main

    def write(relative, **attrs):
        path = tmp_path / "results" / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        xr.Dataset(attrs={"created": "now", **attrs}).to_netcdf(path)

    write("mesh/coarse.nc", stage="mesh", mesh_level="coarse")
    write("mesh/medium.nc", stage="mesh", mesh_level="medium")
    write("scenes/a/summary.nc", stage="scene", scene="a", datasets='["mesh/coarse.nc"]')
    write("scenes/b/summary.nc", stage="scene", scene="b", datasets='["mesh/coarse.nc", "mesh/medium.nc"]')
    write("scenes/c/summary.nc", stage="scene", scene="c", datasets="not json")     # damaged: names nothing
    write("scenes/d/summary.nc", stage="scene", scene="d")                          # older: no lineage

    assert main(["list", str(tmp_path / "results") + "/"]) == 0
    rows = {Path(line.split()[0]).relative_to(tmp_path / "results").as_posix(): line.split()[1:3]
            for line in capsys.readouterr().out.splitlines()[1:]}
    assert rows["mesh/coarse.nc"] == ["mesh", "a,b"] and rows["mesh/medium.nc"] == ["mesh", "b"]
    assert rows["scenes/c/summary.nc"] == ["scene", "c"] and rows["scenes/d/summary.nc"] == ["scene", "d"]

    assert main(["list", str(tmp_path / "results/mesh")]) == 0     # no summary below: scenes unknown
    out = capsys.readouterr().out
    assert [line.split()[2] for line in out.splitlines()[1:3]] == ["?", "?"]
    assert "list the whole results folder" in out
