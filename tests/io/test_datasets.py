"""write_netcdf and write_text: atomic (a temporary name, then a rename); write_netcdf refuses
unlabelled variables."""

import os
import stat

import numpy as np
import pytest
import xarray as xr

from breastcore.io.datasets import write_netcdf, write_text


def _dataset(value):
    return xr.Dataset({"volume": ("posture", np.array([value, 2.0 * value]),
                                  {"units": "m3", "long_name": "breast volume"})})


def test_write_round_trips_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "sub" / "a.nc"
    write_netcdf(_dataset(1e-4), target)
    with xr.open_dataset(target) as ds:
        np.testing.assert_array_equal(ds["volume"].values, [1e-4, 2e-4])
    assert sorted(p.name for p in target.parent.iterdir()) == ["a.nc"]


def test_a_failed_write_leaves_the_old_file_whole_and_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "a.nc"
    write_netcdf(_dataset(1e-4), target)
    seen = {}

    def half_write(self, path, *args, **kwargs):
        seen["path"] = path
        with open(path, "wb") as stream:        # the bytes a crash would leave behind
            stream.write(b"CDF\x01 half")
        with xr.open_dataset(target) as old:    # a reader meanwhile still sees the whole old file
            seen["old"] = old["volume"].values.copy()
        raise OSError("disk full")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", half_write)
    with pytest.raises(OSError, match="disk full"):
        write_netcdf(_dataset(5e-4), target)
    assert seen["path"] != str(target)
    np.testing.assert_array_equal(seen["old"], [1e-4, 2e-4])
    monkeypatch.undo()
    with xr.open_dataset(target) as ds:
        np.testing.assert_array_equal(ds["volume"].values, [1e-4, 2e-4])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.nc"]


def test_a_variable_without_units_is_refused_before_writing(tmp_path):
    ds = _dataset(1e-4)
    ds["area"] = ("posture", np.ones(2), {"long_name": "skin area"})
    with pytest.raises(ValueError, match=r"\['area'\]"):
        write_netcdf(ds, tmp_path / "a.nc")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)], ids=["022", "077", "002"])
def test_the_file_mode_follows_the_umask(tmp_path, umask, mode):
    """A netCDF dataset gets the mode of the workflow's other files (PNG, CSV, VTU), 0666 less
    the umask; its temporary file was mode 0600 whatever the umask (issue #19, item 9)."""
    old = os.umask(umask)
    try:
        write_netcdf(_dataset(1e-4), tmp_path / "a.nc")
        write_netcdf(_dataset(2e-4), tmp_path / "a.nc")           # replacing a file: the same
        with open(tmp_path / "b.csv", "w") as stream:             # what any other writer gets
            stream.write("x\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.nc").stat().st_mode) == mode
    assert stat.S_IMODE((tmp_path / "b.csv").stat().st_mode) == mode


def test_write_text_replaces_whole_and_leaves_no_temporary(tmp_path, monkeypatch):
    target = tmp_path / "report" / "front.html"
    write_text("<p>first</p>\n", target)
    assert target.read_text(encoding="utf-8") == "<p>first</p>\n"
    real_replace = os.replace

    def check_then_replace(src, dst):               # just before the rename, readers see the old page
        assert target.read_text(encoding="utf-8") == "<p>first</p>\n" and str(src) != str(target)
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", check_then_replace)
    write_text("<p>second, μ</p>\n", target)
    assert target.read_text(encoding="utf-8") == "<p>second, μ</p>\n"
    assert sorted(p.name for p in target.parent.iterdir()) == ["front.html"]
