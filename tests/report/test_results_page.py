"""The results page's tables, on small hand-made summaries: ours beside the paper's."""

import numpy as np
import pytest
import xarray as xr

from breastcore.model.parameters import IDENTIFIED
from breastcore.report import paper_values as paper
from breastcore.report.results_page import evolution_table, level_table, measurement_table, paper_comparison_table


def summary(meshes, errors, times, offsets=None):
    n = len(meshes)
    return xr.Dataset({
        "mesh": ("run", np.array(meshes)), "relative_error": (("run", "parameter"), np.array(errors, float)),
        "wall_time": ("run", np.array(times, float)), "iterations": ("run", np.arange(n) + 10),
        "measurement_residual": ("run", np.linspace(0.01, 0.02, n)), "cost": ("run", np.linspace(1e-3, 2e-3, n)),
        "offset": ("run", np.array(offsets or [0.3] * n)),
        "final_measurement_error": (("run", "posture", "quantity"), np.linspace(-0.05, 0.05, n * 15).reshape(n, 3, 5)),
    }, coords={"parameter": list(IDENTIFIED)})


def test_comparison_pairs_our_mean_error_with_the_papers_row_and_keeps_its_other_rows():
    rng = np.random.default_rng(0)
    errors = rng.uniform(-0.5, 0.5, (3, 6))
    table = paper_comparison_table(summary(["coarse", "coarse", "medium"], errors, [1, 3, 5]), "annex_a")
    ours = table[table["source"] == "ours (2 runs)"].iloc[0]
    assert ours["mesh"] == "coarse"
    assert ours[list(IDENTIFIED)].to_numpy(float) == pytest.approx(100 * np.abs(errors[:2]).mean(axis=0))
    assert ours["time_s"] == 2 and ours["iterations"] == 10.5
    papers = table[table["source"] == "paper"].set_index("mesh")
    assert papers.loc["coarse", "mu_skin"] == 15.72 and papers.loc["coarse", "time_s"] == 196
    assert np.isnan(papers.loc["medium", "R"])                      # the annex has no 572-node row
    # rows the scene did not run are kept, with the paper's cycles and time
    assert papers.loc["ultra-thin", "iterations"] == 14 and papers.loc["ultra-thin", "time_s"] == 1587
    assert list(table["mesh"]) == ["coarse", "coarse", "medium", "medium", "medium-thin", "ultra-thin"]


def test_level_table_orders_by_node_count_and_computes_the_papers_residual():
    ds = summary(["medium", "coarse", "medium"], np.zeros((3, 6)), [6, 2, 8])
    gap = np.full((2, 3, 5), 0.02)
    gap[1] = 0.01
    ds["discretisation_error"] = (("level", "posture", "quantity"), gap)
    ds = ds.assign_coords(level=["coarse", "medium"])
    table = level_table(ds)
    assert list(table.index) == ["coarse", "medium"]
    assert list(table["relative_time"]) == [1.0, 3.5]               # median 7 s over the coarse 2 s
    assert table.loc["coarse", "residual_at_truth"] == pytest.approx(4e-4)
    assert table.loc["medium", "residual_at_truth"] == pytest.approx(1e-4)
    assert table.loc["medium", "paper_residual_at_truth"] == paper.TABLE2["medium"]["residual"]


def test_measurement_table_sets_the_papers_case_a_rows_beside_only_when_asked():
    ds = summary(["coarse", "coarse"], np.zeros((2, 6)), [1, 1])
    plain = measurement_table(ds)
    assert list(plain["mesh"]) == ["coarse (ours)"]
    expected = 100 * np.abs(ds["final_measurement_error"].values.reshape(2, 15)).mean(axis=0)
    assert plain.iloc[0][[f"m{i}" for i in range(1, 16)]].to_numpy(float) == pytest.approx(expected)
    assert plain.iloc[0]["avg"] == pytest.approx(expected.mean())
    beside = measurement_table(ds, with_paper=True)
    assert list(beside["mesh"]) == ["coarse (ours)", "Coarse (paper)", "Medium (paper)", "Thin (paper)"]
    assert beside.iloc[1]["m5"] == 6.53 and np.isnan(beside.iloc[1]["cost"])


def test_evolution_table_is_unsigned_like_the_paper_and_shows_its_row_once_per_mesh(tmp_path):
    """Built from the summary alone: its identification files (not inputs of the rule) need not exist."""
    from breastcore.report.summaries import _histories
    truth = np.array([0.05, 0.04, 1000.0, 150.0, 8000.0, 1600.0])
    runs = []
    for k in range(2):
        length = 26 if k == 0 else 20                                  # the second run stopped earlier
        factors = np.ones((length, 6))
        factors[15:, 2] = 0.9 + 0.01 * np.arange(length - 15) * (k + 1) / 10      # λ 10 % low, drifting
        runs.append(xr.Dataset({"parameters": (("iteration", "parameter"), truth * factors),
                                "truth": ("parameter", truth)}))
    ds = xr.Dataset({"mesh": ("run", ["thin", "thin"]), "method": ("run", ["gn", "gn"]),
                     "identification": ("run", [str(tmp_path / "gone0.nc"), str(tmp_path / "gone1.nc")]),
                     "relative_error_history": (("run", "iteration", "parameter"), _histories(runs))})
    table = evolution_table(ds)
    assert list(table["source"]) == ["ours, gn", "paper", "ours, gn"]
    window = 100 * (0.9 + 0.01 * np.arange(11) / 10 - 1)
    assert table.iloc[0]["lambda_breast mean %"] == pytest.approx(np.abs(window).mean())
    assert table.iloc[0]["lambda_breast sd %"] == pytest.approx(window.std(ddof=1))
    assert table.iloc[0]["R mean %"] == pytest.approx(0, abs=1e-12)
    assert table.iloc[1]["lambda_breast mean %"] == paper.EVOLUTION_MEAN["thin"]["lambda_breast"]
    assert table.iloc[2]["iterations"] == "15–19"                    # its NaN padding is not a window
    short = 100 * (0.9 + 0.01 * np.arange(5) * 2 / 10 - 1)
    assert table.iloc[2]["lambda_breast mean %"] == pytest.approx(np.abs(short).mean())


def test_discretisation_error_is_zero_against_itself_and_nan_where_a_solve_did_not_converge(tmp_path):
    from breastcore.io.datasets import open_dataset, write_netcdf
    from breastcore.report.summaries import discretisation_error
    from breastcore.stages.mesh import run_mesh
    from breastcore.stages.solve import run_solve

    run_mesh({"level": "coarse"}, tmp_path / "mesh.nc")
    postures = [{"name": "standing", "angle": 0.0}, {"name": "fours", "angle": 90.0}]
    run_solve({"parameters": {}, "postures": postures, "solver": {}}, tmp_path / "mesh.nc", tmp_path / "a.nc")
    with open_dataset(tmp_path / "a.nc") as ds:
        failed = ds.load()
    failed["converged"].values[0] = 0                                  # as if standing had not converged
    write_netcdf(failed, tmp_path / "b.nc")
    gap, level = discretisation_error(str(tmp_path / "a.nc"), {"coarse": str(tmp_path / "a.nc"),
                                                               "other": str(tmp_path / "b.nc")}, "paper15")
    assert list(level.values) == ["coarse", "other"] and gap.dims == ("level", "posture", "quantity")
    assert np.all(gap.values[0] == 0)
    assert np.all(np.isnan(gap.values[1, 0])) and np.all(gap.values[1, 1] == 0)
