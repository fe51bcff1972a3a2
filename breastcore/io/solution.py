"""Solve several postures and store them as the solution dataset (issue #2, §5)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from breastcore.forward.records import PostureSolution
from breastcore.io.datasets import _var, mesh_coords, mesh_from_dataset, mesh_variables, parameter_variables, provenance
from breastcore.model.parameters import Parameters
from breastcore.model.postures import Posture
from breastcore.model.sliding import REGIME_MARGIN, regime_warning, sliding_margin
from breastcore.model.stability import saddle_warning, stretch_warning
from breastcore.model.torso import penetration_warning
from breastcore.problem import ProblemSpec

if TYPE_CHECKING:                      # numba and PARDISO load with it: not needed to read a dataset
    from breastcore.forward.model import ForwardModel

#: Per-posture solver diagnostics stored in the dataset: name -> (units, long name).
DIAGNOSTICS = {
    "newton_iterations": ("1", "minimiser iterations over all continuation steps"),
    "continuation_steps": ("1", "continuation steps (gravity ramp and δ decrease)"),
    "gradient_norm": ("N", "free-dof gradient norm of the discrete energy at the solution"),
    "tolerance": ("N", "stopping tolerance: rtol × gravity load norm"),
    "energy": ("J", "discrete energy J_h at the solution"),
    "min_det_F": ("1", "smallest det F over the tetrahedra"),
    "max_stretch": ("1", "largest principal stretch over the tetrahedra"),
    "negative_eigenvalues": ("1", "negative eigenvalues of the exact Hessian at the solution "
                                  "(0: a stable minimum; -1: not known, no PARDISO inertia)"),
    "torso_penetration": ("m", "largest depth of a node behind the torso plane y = 0 (0: none; the model "
                               "has no chest-wall contact)"),
    "wall_time": ("s", "wall-clock time of the solve"),
}


def shape_warning(params: Parameters, solutions) -> str:
    """The warnings of shapes outside the model's regime, joined by "; " (``""``: none).

    The sliding margin of ``params`` (:func:`~breastcore.model.sliding.regime_warning`),
    and in each of ``solutions`` the tissue behind the torso plane
    (:func:`~breastcore.model.torso.penetration_warning`), a saddle
    (:func:`~breastcore.model.stability.saddle_warning`) and a stretch beyond soft tissue
    (:func:`~breastcore.model.stability.stretch_warning`).
    """
    depths = {s.posture.name: s.torso_penetration for s in solutions}
    saddles = saddle_warning({s.posture.name: s.negative_eigenvalues for s in solutions})
    stretches = stretch_warning({s.posture.name: s.max_stretch for s in solutions})
    return "; ".join(w for w in (regime_warning(params), penetration_warning(depths), saddles, stretches) if w)


def solve_postures(model: ForwardModel, params: Parameters, postures, starts=None) -> list[PostureSolution]:
    """Equilibrium of each posture; ``starts`` maps posture name to a warm start ``(N, 3)``."""
    starts = starts or {}
    return [model.solve(params, p, starts.get(p.name)) for p in postures]


def solution_dataset(mesh, problem: ProblemSpec, solutions, *, mesh_level="custom", config_hash=None) -> xr.Dataset:
    """The solution dataset: mesh, parameters, positions and diagnostics per posture.

    ``problem`` (its parameters, solver options and postures) is stored in the
    attribute ``problem``; the solutions must be those of its postures, in order.
    """
    names = [s.posture.name for s in solutions]
    if tuple(s.posture for s in solutions) != problem.postures:
        raise ValueError(f"solutions of postures {names} for a problem of {[p.name for p in problem.postures]}")
    params, options = problem.parameters, problem.solver
    data = mesh_variables(mesh)
    data.update(parameter_variables(params))
    data["position"] = _var(("posture", "node", "xyz"), np.stack([s.position for s in solutions]), "m",
                            "equilibrium node position under gravity (torso frame)")
    data["gravity"] = _var(("posture", "xyz"), np.stack([s.posture.gravity(params.gravity_magnitude) for s in solutions]),
                           "m s-2", "gravitational acceleration a_g in the torso frame")
    data["posture_angle"] = _var(("posture",), np.array([s.posture.angle for s in solutions]), "degree",
                                 "forward-bend angle θ")
    data["sliding_margin"] = _var((), sliding_margin(params), "1",
                                  f"c / (ρ g V/|Γ_B|): the Chassaignac coefficient over the stress at which the back "
                                  f"holds the breast's weight; below {REGIME_MARGIN:g} the standing breast slides")
    data["converged"] = _var(("posture",), np.array([s.converged for s in solutions], np.int8), "1",
                             "1 if the solve met its tolerance")
    for name, (units, long_name) in DIAGNOSTICS.items():
        attr = "iterations" if name == "newton_iterations" else name
        data[name] = _var(("posture",), np.array([getattr(s, attr) for s in solutions]), units, long_name)
    coords = mesh_coords()
    coords["posture"] = _var(("posture",), np.array(names), "1", "posture name")
    ds = xr.Dataset(data, coords=coords)
    ds.attrs = provenance("solve", params, config_hash, mesh_level=mesh_level, solver=options.method,
                          regime_warning=shape_warning(params, solutions),
                          title="breastcore equilibrium shapes per posture", **problem.attrs())
    return ds


def postures_from_dataset(ds: xr.Dataset) -> list[Posture]:
    return [Posture(str(n), float(a)) for n, a in zip(ds["posture"].values, ds["posture_angle"].values)]


def equilibrium_residual(ds: xr.Dataset, posture: str):
    """Recompute ``(‖free-dof gradient‖, tolerance)`` in N from a saved solution.

    Independent of the solver's own bookkeeping: rebuilds the mesh, parameters and
    energy from the dataset and differentiates the discrete energy at ``position``.
    """
    spec = ProblemSpec.from_dataset(ds)
    params = spec.parameters
    model = spec.forward_model(mesh_from_dataset(ds))
    p = next(p for p in spec.postures if p.name == posture)
    problem = model.problem(params, p)
    x = ds["position"].sel(posture=posture).values
    return float(np.linalg.norm(problem.gradient(problem.free(x)))), model.tolerance(params, p)
