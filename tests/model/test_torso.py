"""Tissue behind the torso plane: the depth by hand, the warning's bound, and its path to the user."""

import logging

import numpy as np
import pytest

from breastcore.model.torso import PENETRATION_LIMIT, penetration_warning, torso_penetration


def test_penetration_is_the_deepest_node_behind_the_plane():
    x = np.array([[0.0, 0.0, 0.0], [0.01, 0.02, -0.03], [0.0, -0.0025, -0.06], [0.0, -0.001, -0.05]])
    assert torso_penetration(x) == 0.0025
    assert torso_penetration(np.abs(x)) == 0.0                   # all in front of (or on) the plane
    assert not np.signbit(torso_penetration(np.abs(x)))           # 0, not -0 (a node on the plane)
    x[1, 1] = np.nan
    assert np.isnan(torso_penetration(x))                          # not "nothing behind the plane"
    with pytest.raises(IndexError):
        torso_penetration(np.zeros((3, 1)))


def test_the_penetration_warning_fires_above_the_limit_and_not_at_or_below():
    assert penetration_warning({"standing": PENETRATION_LIMIT, "fours": 0.0}) == ""
    assert penetration_warning({"standing": 0.99 * PENETRATION_LIMIT}) == ""
    text = penetration_warning({"standing": 1.5 * PENETRATION_LIMIT, "bent45": 0.5 * PENETRATION_LIMIT})
    assert "standing 1.5 mm" in text and "bent45" not in text and "chest wall" in text
    assert "fours not finite" in penetration_warning({"fours": float("nan")})          # not "nan mm"


def test_a_solve_behind_the_plane_is_recorded_and_warned(tmp_path, caplog):
    """Medium mesh, Λ̄ at c = 100 Pa (the sliding regime): standing passes ~7 mm behind the plane.

    The depth is the dataset's variable, by the solution's own positions; the warning is in
    the dataset, in ``show`` and in the solve stage's log. At the default c neither fires.
    """
    import xarray as xr

    from breastcore.cli.browse import describe
    from breastcore.io.datasets import mesh_dataset, write_netcdf
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    from breastcore.report.summaries import solution_summary
    from breastcore.stages.solve import run_solve

    mesh = mesh_level("medium")
    mesh_path = write_netcdf(mesh_dataset(mesh, "medium", 0.0), tmp_path / "mesh.nc")
    postures = [{"name": "standing", "angle": 0.0}, {"name": "fours", "angle": 90.0}]
    for c, warned in ((100.0, True), (Parameters().chassaignac, False)):
        out = tmp_path / f"solve-{c:g}.nc"
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="breastcore"):
            run_solve({"parameters": {"chassaignac": c}, "postures": postures, "solver": {}}, mesh_path, out)
        with xr.open_dataset(out) as ds:
            depth = ds["torso_penetration"]
            assert depth.attrs["units"] == "m"
            for i in range(len(postures)):
                assert float(depth[i]) == max(0.0, -float(ds["position"][i, :, 1].min()))
            standing = float(depth.sel(posture="standing"))
            assert (standing > PENETRATION_LIMIT) == warned, standing
            assert ("tissue behind the torso plane" in ds.attrs["regime_warning"]) == warned
            assert ("WARNING: " in describe(ds)) == warned
        summary = solution_summary(out, "fwd", "forward")                  # the forward scene's summary
        assert ("tissue behind the torso plane" in summary.attrs.get("regime_warning", "")) == warned
        assert float(summary["torso_penetration"].sel(posture="standing")) == standing
        assert ("WARNING: " in describe(summary)) == warned
        assert any("behind the torso plane" in r.getMessage() for r in caplog.records) == warned
