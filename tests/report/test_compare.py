"""``compare_results``: two results folders, paired by scene, by reference and by name, compared exactly."""

import json

import numpy as np
import pytest
import xarray as xr

from breastcore.cli.main import main as cli_main
from breastcore.report.compare import compare_results, render

#: The same datasets under other names on the two sides (readable names, other keys), as after a refactoring.
NAMES_A = {"mesh": "mesh/coarse.nc", "solve": "solve/0123456789.nc", "measure": "measure/89abcdef01.nc",
           "identify_1": "identify/aaaaaaaaaa.nc", "identify_2": "identify/bbbbbbbbbb.nc",
           "scene": "scenes/demo/summary.nc"}
NAMES_B = {"mesh": "mesh/coarse-v2.nc", "solve": "solve/coarse-standing-fedcba9876.nc",
           "measure": "measure/coarse-paper15-1111111111.nc", "identify_1": "identify/lm-start0-2222222222.nc",
           "identify_2": "identify/lm-start1-3333333333.nc", "scene": "scenes/demo/summary.nc"}


def _identify(measure_path, estimate):
    return xr.Dataset(
        {"estimate": ("parameter", np.array(estimate), {"units": "m m Pa", "long_name": "identified parameters"}),
         "interval_low": ("parameter", np.array([0.05, np.nan, 900.0]), {"units": "m m Pa"}),
         "wall_time": ("iteration", np.array([0.0, 1.25, 2.5]), {"units": "s", "long_name": "wall time"})},
        coords={"parameter": ["R", "H", "lambda_breast"]},
        attrs={"stage": "identify", "measurements": measure_path, "verdict": "consistent"})


def build_results(root, names, created="2026-01-01T00:00:00", edit=None):
    """A tiny results folder ``root/results``: the datasets at ``names``; ``edit(role, ds)`` may change one first."""
    results = root / "results"
    ref = {role: f"results/{name}" for role, name in names.items()}          # written relative to the workdir
    datasets = {
        "mesh": xr.Dataset({"reference_position": (("node", "xyz"), np.arange(12.0).reshape(4, 3) / 7,
                                                   {"units": "m", "long_name": "gravity-free node position"})},
                           coords={"xyz": ["x", "y", "z"]}, attrs={"stage": "mesh", "mesh_level": "coarse"}),
        "solve": xr.Dataset({"position": (("node", "xyz"), np.arange(12.0).reshape(4, 3) / 3, {"units": "m"}),
                             "wall_time": ("posture", np.array([0.5, 0.75]), {"units": "s"}),
                             "assembly_time": ("posture", np.array([0.1, 0.2]), {"units": "s"})},
                            attrs={"stage": "solve", "mesh": ref["mesh"],
                                   "problem": json.dumps({"mesh": ref["mesh"], "rtol": 1e-8})}),
        "measure": xr.Dataset({"measurement": ("quantity", np.array([1.5e-4, 0.031]), {"units": "m3 m"})},
                              attrs={"stage": "measure", "source": ref["solve"]}),
        "identify_1": _identify(ref["measure"], [0.056, 0.05, 1000.0]),
        "identify_2": _identify(ref["measure"], [0.057, 0.049, 1100.0]),
        "scene": xr.Dataset({"identification": ("run", np.array([ref["identify_1"], ref["identify_2"]], dtype=object)),
                             "mean_abs_error": ("run", np.array([0.01, 0.02]), {"units": "1"})},
                            attrs={"stage": "scene", "datasets": json.dumps([names["identify_1"], names["measure"]])}),
    }
    for role, ds in datasets.items():
        ds.attrs.update(created=created, source_hash=created[-8:], config_hash=names[role][-13:-3])
        if edit is not None:
            edit(role, ds)
        (results / names[role]).parent.mkdir(parents=True, exist_ok=True)
        ds.to_netcdf(results / names[role])
    return results


@pytest.fixture
def folder_a(tmp_path):
    return build_results(tmp_path / "a", NAMES_A)


def test_identical_content_under_other_names_pairs_every_file(tmp_path, folder_a):
    folder_b = build_results(tmp_path / "b", NAMES_B, created="2027-06-30T12:00:00")
    assert set(NAMES_A.values()) & set(NAMES_B.values()) == {"scenes/demo/summary.nc"}     # scene folders only
    result = compare_results(folder_a, folder_b)
    assert result.identical, render(result)
    assert result.pairs == len(NAMES_A) and not result.unpaired_a and not result.unpaired_b
    assert set(result.paired) == {(NAMES_A[role], NAMES_B[role]) for role in NAMES_A}
    assert render(result).splitlines()[-1].startswith("IDENTICAL")


def test_one_ulp_in_an_identify_variable_is_a_difference(tmp_path, folder_a):
    def nudge(role, ds):
        if role == "identify_2":
            ds["estimate"].values[2] = np.nextafter(ds["estimate"].values[2], np.inf)
    result = compare_results(folder_a, build_results(tmp_path / "b", NAMES_B, edit=nudge))
    assert not result.identical
    assert len(result.differences) == 1, result.differences
    line = result.differences[0]
    assert NAMES_A["identify_2"] in line and NAMES_B["identify_2"] in line
    assert "'estimate'" in line and "1 of 3 entries differ" in line
    assert render(result).splitlines()[-1].startswith("DIFFERENT")


def test_wall_times_are_not_compared(tmp_path, folder_a):
    def slower(role, ds):
        for name in ("wall_time", "assembly_time"):     # by name, and by units "s"
            if name in ds:
                ds[name].values[:] = ds[name].values * 3 + 1
    assert compare_results(folder_a, build_results(tmp_path / "b", NAMES_B, edit=slower)).identical


def test_an_unpaired_file_differs_unless_allowed(tmp_path, folder_a):
    folder_b = build_results(tmp_path / "b", NAMES_B)
    xr.Dataset({"x": ("i", [1.0])}, attrs={"stage": "solve"}).to_netcdf(folder_b / "solve/extra.nc")
    strict = compare_results(folder_a, folder_b)
    assert not strict.identical and strict.unpaired_b == ("solve/extra.nc",) and not strict.differences
    assert "unpaired in B: solve/extra.nc" in render(strict)
    allowed = compare_results(folder_a, folder_b, allow_unpaired=True)
    assert allowed.identical and allowed.unpaired_b == ("solve/extra.nc",)


def test_a_changed_units_attribute_is_a_difference(tmp_path, folder_a):
    def millimetres(role, ds):
        if role == "mesh":
            ds["reference_position"].attrs["units"] = "mm"
    result = compare_results(folder_a, build_results(tmp_path / "b", NAMES_B, edit=millimetres))
    assert not result.identical
    assert any(NAMES_B["mesh"] in line and "'units'" in line for line in result.differences), result.differences


def test_references_pair_by_position_so_swapped_runs_differ(tmp_path, folder_a):
    def swap(role, ds):
        if role == "scene":
            ds["identification"].values[:] = ds["identification"].values[::-1].copy()
            ds.attrs["datasets"] = json.dumps([NAMES_B["identify_2"], NAMES_B["measure"]])
    result = compare_results(folder_a, build_results(tmp_path / "b", NAMES_B, edit=swap))
    assert (NAMES_A["identify_1"], NAMES_B["identify_2"]) in result.paired
    assert any("'estimate'" in line for line in result.differences) and not result.identical

    def swap_the_variable_only(role, ds):
        if role == "scene":
            ds["identification"].values[:] = ds["identification"].values[::-1].copy()
    result = compare_results(folder_a, build_results(tmp_path / "c", NAMES_B, edit=swap_the_variable_only))
    assert any("at the same place, but they are paired" in line for line in result.differences), result.differences


def test_paths_resolve_in_a_moved_folder(tmp_path, folder_a):
    moved = build_results(tmp_path / "b", NAMES_B).rename(tmp_path / "b" / "results-after")
    result = compare_results(folder_a, moved)
    assert result.identical and result.pairs == len(NAMES_A), render(result)


def test_exit_status_of_the_command_and_the_module(tmp_path, folder_a, capsys):
    from breastcore.cli import compare
    from breastcore.cli.options import UsageError, _Parser

    parser = _Parser(prog="breastcore")
    compare.register(parser.add_subparsers(dest="command", parser_class=_Parser))
    same = build_results(tmp_path / "b", NAMES_B)
    args = parser.parse_args(["compare", str(folder_a), str(same)])
    assert args.run(args) == 0 and "IDENTICAL" in capsys.readouterr().out

    def shift(role, ds):
        if role == "measure":
            ds["measurement"] = ds["measurement"] * 2
    other = build_results(tmp_path / "c", NAMES_B, edit=shift)
    args = parser.parse_args(["compare", str(folder_a), str(other)])
    assert args.run(args) == 1 and "DIFFERENT" in capsys.readouterr().out
    assert cli_main(["compare", str(folder_a), str(other)]) == 1
    assert cli_main(["compare", str(folder_a), str(same)]) == 0
    with pytest.raises(UsageError, match="not a folder holding .nc datasets"):
        parser.parse_args(["compare", str(folder_a), str(tmp_path / "nowhere")])


def test_a_folder_without_scenes_pairs_by_path_and_equals_itself(tmp_path):
    """Paths were paired only after a scene had been compared: a solve/ folder alone read
    'DIFFERENT: 0 differences, 4 unpaired, 0 pairs compared' against itself."""
    import shutil

    def without_scenes(results):
        shutil.rmtree(results / "scenes")
        return results

    folder = without_scenes(build_results(tmp_path / "a", NAMES_A))
    result = compare_results(folder, folder)
    assert result.identical and result.pairs == len(NAMES_A) - 1 and not result.unpaired_a, render(result)

    def nudge(role, ds):
        if role == "solve":
            ds["position"].values[0, 0] += 1e-9          # one value, attributes kept
    changed = without_scenes(build_results(tmp_path / "b", NAMES_A, edit=nudge))
    assert not compare_results(folder, changed).identical
