"""Stage ``uniqueness``: cold solves at Λ̄ (1 ± ε e_j) on one level, for one Chassaignac c."""

from __future__ import annotations

from breastcore.forward.model import ForwardModel
from breastcore.forward.options import SolverOptions
from breastcore.io.datasets import mesh_from_dataset, open_dataset, write_netcdf
from breastcore.model.postures import Posture
from breastcore.studies.calibration import uniqueness_dataset


def run_uniqueness(spec, mesh_path, out, config_hash=None):
    """The uniqueness probe of ``spec`` (``truth``, ``constants``, ``solver``, ``postures``,
    ``measurement_set``, ``epsilon``); failed solves are recorded, never raised."""
    mesh_ds = open_dataset(mesh_path)
    model = ForwardModel(mesh_from_dataset(mesh_ds), SolverOptions(**spec["solver"]))
    postures = tuple(Posture(p["name"], p["angle"]) for p in spec["postures"])
    ds = uniqueness_dataset(model, mesh_ds.attrs["mesh_level"], spec["truth"], spec["constants"], postures,
                            spec["measurement_set"], spec["epsilon"], config_hash)
    write_netcdf(ds, out)
