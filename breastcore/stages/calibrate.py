"""Stage ``calibrate``: cold solves at the truth and the box corners on one level, for one Chassaignac c."""

from __future__ import annotations

from breastcore.forward.model import ForwardModel
from breastcore.forward.options import SolverOptions
from breastcore.io.datasets import mesh_from_dataset, open_dataset, write_netcdf
from breastcore.model.postures import Posture
from breastcore.studies.calibration import level_points_dataset


def run_calibrate(spec, mesh_path, out, config_hash=None):
    """Solve every point of ``spec["points"]`` in every posture, cold; a failed solve is recorded, never raised.

    ``spec``: ``level``, ``points`` (``[{"label", "parameters"}]``, the truth first),
    ``constants`` (with the job's ``chassaignac``), ``solver``, ``postures``
    (``[{"name", "angle"}]``) and ``measurement_set``.
    """
    mesh_ds = open_dataset(mesh_path)
    model = ForwardModel(mesh_from_dataset(mesh_ds), SolverOptions(**spec["solver"]))
    postures = tuple(Posture(p["name"], p["angle"]) for p in spec["postures"])
    ds = level_points_dataset(model, mesh_ds.attrs["mesh_level"], [p["label"] for p in spec["points"]],
                              [p["parameters"] for p in spec["points"]], spec["constants"], postures,
                              spec["measurement_set"], config_hash)
    write_netcdf(ds, out)
