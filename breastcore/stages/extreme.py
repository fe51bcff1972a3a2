"""Stage ``extreme``: identification from every extreme guess on inverse-crime data, on one level."""

from __future__ import annotations

from breastcore.io.datasets import mesh_from_dataset, open_dataset, write_netcdf
from breastcore.studies.extreme_guesses import extreme_guess_study


def run_extreme_guesses(spec, mesh_path, out, config_hash=None):
    """Every guess of ``spec`` ends in a recorded outcome; one dataset for the level."""
    write_netcdf(extreme_guess_study(spec, mesh_from_dataset(open_dataset(mesh_path)), config_hash), out)
