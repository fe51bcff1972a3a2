"""Stage ``solve``: the equilibrium of every posture of a job spec, as a solution dataset."""

from __future__ import annotations

from ..datasets import mesh_from_dataset, open_dataset, write_netcdf
from ..forward import SolverOptions
from ..mesh import refold
from ..parameters import Parameters
from ..postures import Posture
from ..problem import ProblemSpec
from ..solution import solution_dataset, solve_postures


def run_solve(spec, mesh_path, out, config_hash=None):
    """Solve ``spec`` (``parameters``, ``postures``, ``solver``) on the mesh and write its problem spec too."""
    mesh_ds = open_dataset(mesh_path)
    problem = ProblemSpec(parameters=Parameters(**spec["parameters"]), solver=SolverOptions(**spec["solver"]),
                          postures=tuple(Posture(p["name"], p["angle"]) for p in spec["postures"]))
    model = problem.forward_model(mesh_from_dataset(mesh_ds))
    params = problem.parameters
    solutions = solve_postures(model, params, problem.postures)
    shown = refold(model.map.mesh_at(params.R, params.H), params.fold_angle)
    write_netcdf(solution_dataset(shown, problem, solutions, mesh_level=mesh_ds.attrs["mesh_level"],
                                  config_hash=config_hash), out)
