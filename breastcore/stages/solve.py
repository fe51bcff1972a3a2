"""Stage ``solve``: the equilibrium of every posture of a job spec, as a solution dataset."""

from __future__ import annotations

import logging

from breastcore.forward.options import SolverOptions
from breastcore.io.datasets import mesh_from_dataset, open_dataset, write_netcdf
from breastcore.io.solution import solution_dataset, solve_postures
from breastcore.model.parameters import Parameters
from breastcore.model.postures import Posture
from breastcore.problem import ProblemSpec

log = logging.getLogger(__name__)


def run_solve(spec, mesh_path, out, config_hash=None):
    """Solve ``spec`` (``parameters``, ``postures``, ``solver``) on the mesh and write its problem spec too."""
    mesh_ds = open_dataset(mesh_path)
    problem = ProblemSpec(parameters=Parameters(**spec["parameters"]), solver=SolverOptions(**spec["solver"]),
                          postures=tuple(Posture(p["name"], p["angle"]) for p in spec["postures"]))
    model = problem.forward_model(mesh_from_dataset(mesh_ds))
    params = problem.parameters
    solutions = solve_postures(model, params, problem.postures)
    shown = model.mesh_at(params)
    ds = solution_dataset(shown, problem, solutions, mesh_level=mesh_ds.attrs["mesh_level"], config_hash=config_hash)
    write_netcdf(ds, out)
    if ds.attrs["regime_warning"]:
        log.warning("shape: %s", ds.attrs["regime_warning"])
