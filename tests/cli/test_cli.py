"""Command line: --help documents every option; bad input is one line, exit 2, no traceback."""

import subprocess
import sys
from pathlib import Path

import pytest

from breastcore.model.parameters import PARAMETER_INFO


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


@pytest.mark.parametrize("kind, words", [("pipe", "not a regular file"), ("folder", "it is a folder"),
                                         ("empty", "not a file name")])
def test_an_output_that_is_no_regular_file_is_refused_before_any_work(tmp_path, capsys, kind, words):
    """The output is renamed over its path: a device or pipe there would be replaced (a review's
    ``--out /dev/null`` replaced the machine's /dev/null). A pipe stands in for the device here."""
    import os
    import stat

    from breastcore.cli.main import main
    target = tmp_path / "target"
    if kind == "pipe":
        os.mkfifo(target)
    elif kind == "folder":
        target.mkdir()
    out = "" if kind == "empty" else str(target)
    assert main(["solve", "--mesh", "coarse", "--out", out]) == 2
    line, = capsys.readouterr().err.strip().splitlines()
    assert "--out" in line and words in line, line
    if kind == "pipe":
        assert stat.S_ISFIFO(os.stat(target).st_mode)


def test_the_atomic_writer_never_renames_over_a_pipe_or_a_folder(tmp_path):
    import os
    import stat

    import xarray as xr

    from breastcore.io.datasets import write_netcdf
    ds = xr.Dataset({"a": ((), 1.0, {"units": "1", "long_name": "a number"})})
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "folder").mkdir()
    with pytest.raises(FileExistsError, match="not a regular file"):
        write_netcdf(ds, tmp_path / "pipe")
    with pytest.raises(IsADirectoryError, match="it is a folder"):
        write_netcdf(ds, tmp_path / "folder")
    assert stat.S_ISFIFO(os.stat(tmp_path / "pipe").st_mode) and sorted(os.listdir(tmp_path)) == ["folder", "pipe"]


def test_export_refuses_an_out_dir_that_is_a_file(tmp_path, files, capsys):
    from breastcore.cli.main import main
    (tmp_path / "file").write_text("")
    assert main(["export", str(files["solve"]), "--out-dir", str(tmp_path / "file")]) == 2
    line, = capsys.readouterr().err.strip().splitlines()
    assert "--out-dir" in line and "a file, not a folder" in line, line


@pytest.mark.parametrize("value", ["1.5", "-0.1"])
def test_bad_identify_cost_rtol_is_one_line_naming_the_option(tmp_path, value, files):
    out = run("identify", "--measurements", files["measure"], "--cost-rtol", value,
              "--out", str(tmp_path / "x.nc"))
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "--cost-rtol" in lines[0], out.stderr
    assert not (tmp_path / "x.nc").exists()


def test_list_names_the_scenes_each_dataset_serves(tmp_path, capsys):
    import xarray as xr

    from breastcore.cli.main import main

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


# --- every numeric option: its range is stated in --help and enforced by argparse ----------------
#
# The contract: the valid range of every numeric option, as its --help states it. A new numeric
# option missing here fails test_every_numeric_option_has_a_stated_range; one listed here but
# converted by plain float/int fails the bad-value tests.

POSITIVE, NON_NEGATIVE, UNIT_OPEN, UNIT_HALF_OPEN, COUNT = "> 0", ">= 0", "in (0, 1)", "in [0, 1)", "integer >= 1"
FOLD = "in (0, 360]"
PARAMETER_RANGES = {"R": POSITIVE, "H": POSITIVE, "lambda_breast": NON_NEGATIVE, "mu_breast": POSITIVE,
                    "lambda_skin": NON_NEGATIVE, "mu_skin": NON_NEGATIVE, "skin_thickness": NON_NEGATIVE,
                    "density": POSITIVE, "gravity_magnitude": NON_NEGATIVE, "chassaignac": NON_NEGATIVE,
                    "smoothing": POSITIVE, "fold_angle": FOLD}
_PARAMETER_OPTIONS = {PARAMETER_INFO[name].cli: kind for name, kind in PARAMETER_RANGES.items()}
RANGES = {
    "solve": {"--rtol": UNIT_OPEN, "--mesh-size": POSITIVE, **_PARAMETER_OPTIONS},
    "identify": {"--mesh-size": POSITIVE, "--rtol": UNIT_OPEN, "--fd-step": UNIT_OPEN, "--cost-tol": NON_NEGATIVE,
                 "--cost-rtol": UNIT_HALF_OPEN, "--max-iterations": COUNT, "--noise": POSITIVE,
                 "--initial-trust-radius": POSITIVE, "--warm-radius": NON_NEGATIVE, "--processes": COUNT,
                 **_PARAMETER_OPTIONS},
    "sensitivity": {"--delta": UNIT_OPEN, "--processes": COUNT},
}
BAD_VALUES = {
    POSITIVE: ["0", "-0.0", "-1", "nan", "inf", "-inf", "abc", ""],
    NON_NEGATIVE: ["-1", "-1e-300", "nan", "inf", "-inf", "abc", ""],
    UNIT_OPEN: ["0", "1", "-0.5", "1.5", "nan", "inf", "abc", ""],
    UNIT_HALF_OPEN: ["-0.1", "1", "2", "nan", "inf", "abc", ""],
    FOLD: ["0", "-10", "360.5", "nan", "inf", "abc", ""],
    COUNT: ["0", "-1", "1.5", "nan", "inf", "abc", ""],
}
BAD_NUMBERS = [(command, option, value) for command, options in RANGES.items()
               for option, kind in options.items() for value in BAD_VALUES[kind]]


def parser_options():
    """(command, option) -> argparse action of every optional argument of every sub-command."""
    import argparse

    from breastcore.cli.main import build_parser
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {(command, action.option_strings[-1]): action for command, p in sub.choices.items()
            for action in p._actions if action.option_strings}


def test_every_numeric_option_has_a_stated_range():
    options = parser_options()
    numeric = {key for key, a in options.items()
               if a.type in (int, float) or hasattr(a.type, "range")
               or (isinstance(a.default, (int, float)) and not isinstance(a.default, bool))}
    listed = {(command, option) for command, opts in RANGES.items() for option in opts}
    assert numeric - listed == set(), "numeric options without a range in RANGES"
    assert listed - set(options) == set(), "RANGES lists options the parsers do not have"


@pytest.mark.parametrize("command, option", [(c, o) for c, opts in RANGES.items() for o in opts])
def test_help_states_the_range_the_parser_enforces(command, option):
    action = parser_options()[(command, option)]
    assert getattr(action.type, "range", None) == RANGES[command][option]
    assert RANGES[command][option] in " ".join(action.help.split())


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Cheap inputs: a valid measurement dataset, a stage-only identification and solution, a real
    mesh dataset, and files that are not (readable) breastcore datasets."""
    import numpy as np
    import xarray as xr

    from breastcore.inverse.measurements import QUANTITIES
    from breastcore.io.datasets import mesh_dataset, write_netcdf
    from breastcore.io.patient import PatientMeasurements
    from breastcore.io.targets import measurement_dataset
    from breastcore.model.mesh import LEVEL_MESH_SIZE, mesh_level
    from breastcore.model.postures import Posture

    folder = tmp_path_factory.mktemp("inputs")
    si = np.array([[4.8e-4, 0.031, 0.150, 0.062, 0.055], [4.8e-4, 0.032, 0.140, 0.075, 0.070]])
    target = PatientMeasurements((Posture("standing", 0.0), Posture("bent45", 45.0)), QUANTITIES, si)
    out = {"measure": write_netcdf(measurement_dataset(target, "patient"), folder / "m.nc"),
           "mesh": write_netcdf(mesh_dataset(mesh_level("coarse"), "coarse", LEVEL_MESH_SIZE["coarse"]),
                                folder / "mesh.nc")}
    bad, values = measurement_dataset(target, "patient"), si.copy()
    values[1, 1] = np.nan                                                   # bent45 area
    bad["measurement"] = bad["measurement"].copy(data=values)
    out["nan-measure"] = write_netcdf(bad, folder / "nan_m.nc")
    for stage in ("identify", "solve"):
        out[stage] = folder / f"{stage}.nc"
        xr.Dataset(attrs={"stage": stage}).to_netcdf(out[stage], engine="netcdf4")
    out["no-stage"] = folder / "plain.nc"
    xr.Dataset({"x": ("n", [1.0, 2.0])}).to_netcdf(out["no-stage"], engine="netcdf4")
    (folder / "empty.nc").write_bytes(b"")
    (folder / "text.nc").write_text("posture,quantity,value\nstanding,volume,480\n")
    (folder / "truncated.nc").write_bytes(out["mesh"].read_bytes()[:3000])
    out.update(empty=folder / "empty.nc", text=folder / "text.nc", truncated=folder / "truncated.nc")
    return {k: str(v) for k, v in out.items()}


@pytest.fixture
def no_work(monkeypatch):
    """Replace the sub-commands' run() by a sentinel: bad options must be refused by argparse,
    before any mesh, solve or identification."""
    from breastcore.cli import identify, sensitivity, solve

    def reached(args):
        raise AssertionError(f"{args.command}: run() reached")
    for module in (solve, identify, sensitivity):
        monkeypatch.setattr(module, "run", reached)


def argv(command, files, tmp_path, *extra):
    head = {"solve": ["solve"], "identify": ["identify", "--measurements", files["measure"]],
            "sensitivity": ["sensitivity", files["identify"]]}[command]
    return [*head, *extra, "--out", str(tmp_path / "out.nc")]


def one_error_line(capsys, command):
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(("breastcore: error: ", f"breastcore {command}: error: ")), lines[0]
    return lines[0]


@pytest.mark.parametrize("command, option, value", BAD_NUMBERS)
def test_bad_number_is_one_line_naming_option_and_value(command, option, value, files, tmp_path, capsys,
                                                        no_work):
    from breastcore.cli.main import main
    assert main(argv(command, files, tmp_path, f"{option}={value}")) == 2
    line = one_error_line(capsys, command)
    assert option in line and repr(value) in line, line
    assert not (tmp_path / "out.nc").exists()


@pytest.mark.parametrize("command", list(RANGES))
def test_valid_numbers_reach_run(command, files, tmp_path, capsys, no_work):
    """The converters refuse the bad values only: the bounds themselves where they are allowed."""
    from breastcore.cli.main import main
    good = {POSITIVE: "1e-3", NON_NEGATIVE: "0", UNIT_OPEN: "0.5", UNIT_HALF_OPEN: "0", FOLD: "360", COUNT: "2"}
    extra = [f"{o}={good[kind]}" for o, kind in RANGES[command].items()]
    assert main(argv(command, files, tmp_path, *extra)) == 1
    assert "run() reached" in capsys.readouterr().err


def test_identify_rtol_reaches_the_problem_spec_and_its_forward_model(files, tmp_path, monkeypatch, capsys):
    """``identify --rtol`` sets the forward solver's tolerance, as ``solve --rtol`` does: not the default 1e-8."""
    import breastcore.stages.identify
    from breastcore.cli.main import main
    seen = []

    def spy(mm, target, initial, options, weights=None):
        seen.append(mm.model.options)
        raise RuntimeError("recorded; not run")

    monkeypatch.setattr(breastcore.stages.identify, "identify", spy)
    assert main(argv("identify", files, tmp_path, "--mesh", "coarse", "--rtol", "3e-7", "--solver", "cg")) == 1
    assert "recorded; not run" in capsys.readouterr().err
    assert [(o.rtol, o.method) for o in seen] == [(3e-7, "cg")]


@pytest.mark.parametrize("text, named", [
    ("R=0", "R=0"), ("R=-0.01", "R=-0.01"), ("mu_breast=nan", "mu_breast=nan"), ("H=inf", "H=inf"),
    ("lambda_skin=-1", "lambda_skin=-1"), ("R=abc", "R=abc"), ("R=0.06,R=0.07", "R"), ("Q=1", "Q"),
    ("R", "R"), ("density=1000", "density"),                   # not one of the six identified
])
def test_bad_initial_guess_is_refused_by_the_parser(text, named, files, tmp_path, capsys, no_work):
    from breastcore.cli.main import main
    assert main(argv("identify", files, tmp_path, "--initial", text)) == 2
    line = one_error_line(capsys, "identify")
    assert "--initial" in line and named in line, line


@pytest.mark.parametrize("text, named", [
    ("tilt=nan", "nan"), ("tilt=inf", "inf"), ("tilt=-5", "-5"), ("tilt=91", "91"), ("tilt=abc", "abc"),
    ("tilt=", "tilt="), ("supine", "supine"), ("standing=45", "45"), ("=30", "''"),
])
def test_bad_posture_is_refused_by_the_parser(text, named, files, tmp_path, capsys, no_work):
    from breastcore.cli.main import main
    assert main(argv("solve", files, tmp_path, "--posture", "standing", "--posture", text)) == 2
    line = one_error_line(capsys, "solve")
    assert "--posture" in line and named in line, line


# --- dataset arguments: readable netCDF of the expected stage -----------------------------------

DATASET_ARGUMENTS = {   # command -> (argv with FILE, argument name in the message, expected stage)
    "identify": (lambda f, d: ["identify", "--measurements", f, "--out", f"{d}/o.nc"], "--measurements", "measure"),
    "sensitivity": (lambda f, d: ["sensitivity", f, "--out", f"{d}/o.nc"], "ID.nc", "identify"),
    "export": (lambda f, d: ["export", f, "--out-dir", d], "SOLUTION.nc", "solve"),
    "measure": (lambda f, d: ["measure", f, "--out", f"{d}/o.nc"], "SOLUTION.nc", "solve"),
    "show": (lambda f, d: ["show", f], "FILE.nc", None),
}
BAD_FILES = {"empty": ["empty", "not a netCDF file"], "text": ["not a netCDF file"],
             "truncated": ["cannot be read as netCDF"], "mesh": ["stage 'mesh'"], "no-stage": ["no 'stage'"]}


@pytest.mark.parametrize("command, kind", [(c, k) for c in DATASET_ARGUMENTS for k in BAD_FILES
                                           if DATASET_ARGUMENTS[c][2] or k in ("empty", "text", "truncated")])
def test_bad_dataset_is_one_line_naming_argument_and_problem(command, kind, files, tmp_path, capsys):
    from breastcore.cli.main import main
    build, name, stage = DATASET_ARGUMENTS[command]
    assert main(build(files[kind], str(tmp_path))) == 2
    line = one_error_line(capsys, command)
    assert name in line and files[kind] in line and all(w in line for w in BAD_FILES[kind]), line
    if kind in ("mesh", "no-stage"):
        assert f"expected stage '{stage}'" in line, line
    assert list(tmp_path.iterdir()) == []


def test_dataset_type_returns_the_path_of_an_accepted_stage(files):
    import argparse

    from breastcore.cli.options import dataset_file
    assert dataset_file("solve", "identify")(files["identify"]) == Path(files["identify"])
    assert dataset_file()(files["no-stage"]) == Path(files["no-stage"])      # show: any netCDF
    with pytest.raises(argparse.ArgumentTypeError, match="expected stage 'solve' or 'identify'"):
        dataset_file("solve", "identify")(files["measure"])
    with pytest.raises(argparse.ArgumentTypeError, match="no such file"):
        dataset_file("solve")(files["measure"] + ".missing")


def test_measurement_dataset_with_a_nan_names_the_value(files, tmp_path, capsys, no_work):
    from breastcore.cli.main import main
    assert main(["identify", "--measurements", files["nan-measure"], "--out", str(tmp_path / "o.nc")]) == 2
    line = one_error_line(capsys, "identify")
    assert all(w in line for w in ("--measurements", "bent45", "area", "nan")), line


@pytest.mark.parametrize("weighted, words", [
    ([], ["every weight is 0", "0 measurements cannot determine 6 parameters"]),
    ([(0, 0), (0, 1), (0, 2), (0, 3), (0, 4)], ["only 5 of 10 measurements have weight > 0",
                                                "5 measurements cannot determine 6 parameters"])])
def test_too_few_weighted_measurements_are_refused_while_parsing(weighted, words, files, tmp_path, capsys,
                                                                  no_work):
    """All weights 0 reached the identification, which stopped with a bare ValueError and exit 1."""
    from dataclasses import replace

    import numpy as np

    from breastcore.cli.main import main
    from breastcore.io.datasets import open_dataset, write_netcdf
    from breastcore.io.targets import measurement_dataset, target_from_dataset
    target = target_from_dataset(open_dataset(files["measure"]))          # two postures: 10 measurements
    weights = np.zeros_like(target.weights)
    for index in weighted:
        weights[index] = 1.0
    path = write_netcdf(measurement_dataset(replace(target, weights=weights), "patient"), tmp_path / "w.nc")
    assert main(["identify", "--measurements", str(path), "--out", str(tmp_path / "o.nc")]) == 2
    line = one_error_line(capsys, "identify")
    assert "--measurements" in line and str(path) in line and all(w in line for w in words), line
    assert not (tmp_path / "o.nc").exists()


@pytest.mark.parametrize("value, words", [
    ("-5", ["standing", "volume", "-5 ml", "> 0"]), ("0", ["standing", "volume", "0 ml"]),
    (".nan", ["standing", "volume", "nan ml"])])
def test_bad_patient_value_is_one_line_naming_posture_quantity_and_value(tmp_path, capsys, value, words):
    from breastcore.cli.main import main
    path = tmp_path / "p.yaml"
    path.write_text("postures:\n"
                    f"  standing: {{volume: {value}, area: 310, height: 150, frontal_depth: 62, back_depth: 55}}\n"
                    "  fours: {volume: 480, area: 330, height: 130, frontal_depth: 85, back_depth: 80}\n")
    assert main(["measure", "--patient", str(path), "--out", str(tmp_path / "m.nc")]) == 2
    line = one_error_line(capsys, "measure")
    assert "--patient" in line and all(w in line for w in words), line


def test_unparsable_patient_file_is_one_line(tmp_path, capsys):
    from breastcore.cli.main import main
    (tmp_path / "p.yaml").write_text("postures: [standing\n")
    (tmp_path / "p.csv").write_bytes(b"\xff\xfeposture")
    for name, words in (("p.yaml", ["not valid YAML", "line"]), ("p.csv", ["UTF-8"])):
        assert main(["measure", "--patient", str(tmp_path / name), "--out", str(tmp_path / "m.nc")]) == 2
        line = one_error_line(capsys, "measure")
        assert "--patient" in line and name in line and all(w in line for w in words), line


def test_an_unusual_patient_value_is_one_warning_line(tmp_path):
    """Python's own warning line (``patient.py:NNN: MeasurementWarning:`` and a source line) is not
    printed before the command's: stderr is the one warning, and the dataset is written."""
    path = tmp_path / "p.yaml"
    path.write_text("postures:\n"
                    "  standing: {volume: 601, area: 362, height: 600, frontal_depth: 51, back_depth: 41}\n"
                    "  fours: {volume: 991, area: 242, height: 112, frontal_depth: 66, back_depth: 66}\n")
    out = run("measure", "--patient", str(path), "--out", str(tmp_path / "m.nc"))
    assert out.returncode == 0, out.stderr
    lines = out.stderr.splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith("breastcore measure: warning: posture 'standing': height 600 mm"), lines[0]
    assert (tmp_path / "m.nc").exists()


def test_identify_warns_of_each_input_note_of_its_measurements(tmp_path):
    """The measurement dataset's input_notes (implausible values run as asked, unusual ones) are on
    identify's stderr too, as warnings, not only in the datasets."""
    import json

    from breastcore.io.datasets import open_dataset
    path = tmp_path / "p.yaml"
    path.write_text("postures:\n"
                    "  standing: {volume: 601, area: 362, height: 600, frontal_depth: 51, back_depth: 41}\n"
                    "  fours: {volume: 991, area: 242, height: 112, frontal_depth: 66, back_depth: 66}\n")
    assert run("measure", "--patient", str(path), "--out", str(tmp_path / "m.nc")).returncode == 0
    notes = json.loads(open_dataset(tmp_path / "m.nc").attrs["input_notes"])
    assert notes and any("height 600 mm" in note for note in notes), notes
    out = run("identify", "--measurements", str(tmp_path / "m.nc"), "--mesh", "coarse", "--max-iterations", "1",
              "--out", str(tmp_path / "id.nc"))
    assert (tmp_path / "id.nc").exists(), out.stderr
    lines = out.stderr.splitlines()
    for note in notes:
        assert lines.count(f"breastcore identify: warning: {note}") == 1, out.stderr


def test_an_implausible_patient_is_refused_naming_the_option_that_runs_it(tmp_path, capsys):
    """The command line names its own option, --allow-implausible, not the config key."""
    from breastcore.cli.main import main
    path = tmp_path / "p.yaml"
    path.write_text("postures:\n"
                    "  standing: {volume: 601, area: 1, height: 115, frontal_depth: 51, back_depth: 41}\n"
                    "  fours: {volume: 991, area: 242, height: 112, frontal_depth: 66, back_depth: 66}\n")
    assert main(["measure", "--patient", str(path), "--out", str(tmp_path / "m.nc")]) == 2
    line = one_error_line(capsys, "measure")
    assert "posture 'standing': area 1 cm2" in line and line.endswith("run them flagged with --allow-implausible"), line
    assert "allow_implausible" not in line, line
    assert main(["measure", "--patient", str(path), "--allow-implausible", "--out", str(tmp_path / "m.nc")]) == 0


# --- the closing note's table, end to end in a fresh process -------------------------------------

@pytest.mark.parametrize("case", ["solve --rtol 0", "empty .nc", "text .nc", "mesh to identify", "negative volume"])
def test_bad_input_end_to_end(case, files, tmp_path):
    patient = tmp_path / "p.csv"
    patient.write_text("posture,quantity,value,unit\n" + "".join(
        f"standing,{q},{v},{u}\n" for q, v, u in zip(("volume", "area", "height", "frontal_depth", "back_depth"),
                                                      (-5, 310, 150, 62, 55), ("ml", "cm2", "mm", "mm", "mm"))))
    args, words = {
        "solve --rtol 0": (["solve", "--rtol", "0"], ["--rtol", "'0'", "(0, 1)"]),
        "empty .nc": (["identify", "--measurements", files["empty"]], ["--measurements", "empty", "not a netCDF"]),
        "text .nc": (["identify", "--measurements", files["text"]], ["--measurements", "not a netCDF file"]),
        "mesh to identify": (["identify", "--measurements", files["mesh"]],
                             ["--measurements", "stage 'mesh'", "expected stage 'measure'"]),
        "negative volume": (["measure", "--patient", str(patient)], ["--patient", "standing", "volume", "-5 ml"]),
    }[case]
    out = run(*args, "--out", str(tmp_path / "o.nc"))
    lines = out.stderr.strip().splitlines()
    assert out.returncode == 2 and len(lines) == 1 and "Traceback" not in out.stderr, out.stderr
    assert all(w in lines[0] for w in words), lines[0]


def test_show_into_a_pipe_that_closes_early_prints_no_error(files):
    """`breastcore show x.nc | head -1`: the reader leaves after one line; show says nothing of it."""
    proc = subprocess.Popen([sys.executable, "-m", "breastcore", "show", files["mesh"]], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout.readline()
    proc.stdout.close()
    assert proc.stderr.read() == "" and proc.wait() in (0, 141)


def test_show_of_a_foreign_netcdf_file_says_it_has_no_provenance(files, capsys):
    """It printed 'breastcore None (source None), config None' for a file no breastcore wrote."""
    from breastcore.cli.main import main
    assert main(["show", files["no-stage"]]) == 0
    out = capsys.readouterr().out
    assert "provenance: none (not written by breastcore)" in out and "None" not in out, out


def test_a_measurement_dataset_without_its_variable_is_named_plainly(tmp_path, files, capsys):
    """It read "stage 'measure' dataset without "No variable named 'measurement'. Variables on ..."."""
    from breastcore.cli.main import main
    from breastcore.io.datasets import open_dataset
    broken = open_dataset(files["measure"]).drop_vars("measurement")
    broken.to_netcdf(tmp_path / "m.nc")
    assert main(["identify", "--measurements", str(tmp_path / "m.nc"), "--out", str(tmp_path / "id.nc")]) == 2
    line, = capsys.readouterr().err.strip().splitlines()
    assert line.endswith("stage 'measure' dataset without the variable 'measurement'"), line
