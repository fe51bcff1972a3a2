"""Warnings for equilibria a breast cannot hold: a saddle, a stretch beyond soft tissue. They reach the
dataset, ``breastcore solve`` (exit 1 for a saddle) and ``show``."""

import dataclasses

from breastcore.model.stability import MAX_PLAUSIBLE_STRETCH, saddle_warning, stretch_warning


def test_saddle_warning_names_only_postures_with_negative_eigenvalues():
    assert saddle_warning({"standing": 0, "fours": -1}) == ""          # -1: inertia unknown, not warned
    line = saddle_warning({"standing": 2, "bent45": 0, "fours": 1})
    assert "standing (2 negative eigenvalues)" in line and "fours (1 negative eigenvalue)" in line
    assert "bent45" not in line


def test_stretch_warning_fires_above_the_bound_and_for_nan():
    assert stretch_warning({"standing": 2.5, "fours": MAX_PLAUSIBLE_STRETCH}) == ""
    line = stretch_warning({"standing": 318.0, "fours": 1.6, "bent45": float("nan")})
    assert "standing 318" in line and "bent45 not finite" in line and "fours" not in line


def test_a_solve_ending_on_a_saddle_is_written_warned_and_exits_1(tmp_path, monkeypatch, capsys):
    """The escape can fail to leave a saddle (very soft parameters): the shape is returned, and said to
    be unstable wherever it is read, instead of 'converged' with exit 0."""
    from breastcore.cli.browse import describe
    from breastcore.cli.main import main
    from breastcore.forward.model import ForwardModel
    from breastcore.io.datasets import open_dataset
    real = ForwardModel.solve

    def saddle(self, params, posture, start=None):
        return dataclasses.replace(real(self, params, posture, start), negative_pivots=1)

    monkeypatch.setattr(ForwardModel, "solve", saddle)
    assert main(["solve", "--mesh", "coarse", "--posture", "fours", "--out", str(tmp_path / "s.nc")]) == 1
    err = capsys.readouterr().err
    assert "saddle of the energy, in fours (1 negative eigenvalue)" in err and "not a stable equilibrium" in err
    ds = open_dataset(tmp_path / "s.nc")
    assert int(ds["negative_eigenvalues"].values[0]) == 1 and "saddle" in ds.attrs["regime_warning"]
    assert "WARNING: " in describe(ds) and "saddle of the energy" in describe(ds)


def test_a_stable_ordinary_solve_has_no_such_warning(tmp_path):
    from breastcore.cli.main import main
    from breastcore.io.datasets import open_dataset
    assert main(["solve", "--mesh", "coarse", "--posture", "fours", "--out", str(tmp_path / "s.nc")]) == 0
    warning = open_dataset(tmp_path / "s.nc").attrs["regime_warning"]
    assert "saddle" not in warning and "stretch" not in warning
