"""The identification dataset: history, estimate, shapes, Jacobian and uncertainty."""

from __future__ import annotations

import numpy as np
import xarray as xr

from breastcore.inverse.measurements import QUANTITIES
from breastcore.inverse.uncertainty import (
    DETERMINED_FACTOR,
    LIMIT_FACTOR,
    UNSEEN_SENSITIVITY,
    Z95,
    conditioning,
    determined,
    interval_decades,
    intervals,
    limits,
    log_covariance,
)
from breastcore.inverse.verdict import fit_verdict
from breastcore.io.datasets import (
    PARAMETER_UNIT_LIST,
    QUANTITY_UNIT_LIST,
    _var,
    mesh_coords,
    mesh_variables,
    provenance,
)
from breastcore.io.solution import DIAGNOSTICS, shape_warning
from breastcore.model.parameters import IDENTIFIED, PARAMETER_INFO
from breastcore.model.sliding import REGIME_MARGIN, sliding_margin



def identification_dataset(result, mm, target, problem, *, initial, truth=None, mesh_level="custom",
                           config_hash=None) -> xr.Dataset:
    """Build the dataset of one :class:`~breastcore.inverse.identify.IdentificationResult`.

    ``problem`` is the :class:`~breastcore.problem.ProblemSpec` that built ``mm``; it is
    stored in the attribute ``problem``, and the model's own mesh nodes in
    ``model_reference_position``, so that a later stage (the finite sensitivity)
    rebuilds exactly this problem.
    """
    problem.check_model(mm)
    options = problem.identification
    estimate = np.asarray(result.estimate, float)
    params = mm.params(estimate)                           # Λ̂ with the problem's constants
    J = result.jacobian.reshape(-1, len(IDENTIFIED))
    weights = np.asarray(target.weights, float).ravel()
    cov_log = log_covariance(J, options.noise, weights)
    low, high = intervals(estimate, cov_log)
    singular, rank, cond = conditioning(np.sqrt(weights)[:, None] * J)
    postures = [p.name for p in target.postures]
    verdict = verdict_of(result, target, options.noise)
    data = {
        **_history_variables(result),
        "initial": _var(("parameter",), np.asarray(initial, float), PARAMETER_UNIT_LIST, "initial guess"),
        "estimate": _var(("parameter",), estimate, PARAMETER_UNIT_LIST, "identified parameters"),
        "jacobian": _var(("posture", "quantity", "parameter"), result.jacobian, "1",
                         "relative Jacobian ∂ln M/∂ln Λ at the estimate"),
        **_uncertainty_variables(estimate, cov_log, low, high, options.noise),
        "limit": _var(("parameter",), limits(J, estimate, initial, weights), "1",
                      "0: the measurements see the parameter; unseen by them (its relative-Jacobian column "
                      f"shorter than {UNSEEN_SENSITIVITY:g}), the estimate is a limit: -1 towards 0, 1 towards "
                      f"infinity (more than a factor {LIMIT_FACTOR:g} from the initial guess), 2 no clear direction"),
        "sliding_margin": _var((), sliding_margin(params), "1",
                               f"c / (ρ g V/|Γ_B|) at the estimate; below {REGIME_MARGIN:g} the standing breast "
                               "slides (outside the mesh-converged regime)"),
        "standardised_residual": _var(("posture", "quantity"), np.asarray(result.measurement_error[-1]) / options.noise,
                                      "1", "(M(Λ̂)/M̄ − 1) / σ at the estimate, σ the noise model's relative 1σ"),
        "singular_values": _var(("singular",), singular, "1", "singular values of the weighted relative Jacobian"),
        "target": _var(("posture", "quantity"), target.values, QUANTITY_UNIT_LIST, "measured values M̄"),
        "weight": _var(("posture", "quantity"), target.weights, "1", "weight w_i of the measurement in the cost"),
        "position": _var(("posture", "node", "xyz"),
                         np.stack([result.solutions[p].position for p in postures]), "m",
                         "predicted equilibrium shape at the estimate"),
        "posture_angle": _var(("posture",), np.array([p.angle for p in target.postures]), "degree",
                              "forward-bend angle θ"),
    }
    for name, (units, long_name) in DIAGNOSTICS.items():
        attr = "iterations" if name == "newton_iterations" else name
        data["solve_" + name] = _var(("posture",), np.array([getattr(result.solutions[p], attr) for p in postures]),
                                     units, long_name + " (solve of the final shapes)")
    if truth is not None:
        data["truth"] = _var(("parameter",), np.asarray(truth, float), PARAMETER_UNIT_LIST, "generating parameters")
        data["relative_error"] = _var(("parameter",), estimate / np.asarray(truth, float) - 1.0, "1",
                                      "estimate / truth − 1")
    shown = mm.model.mesh_at(params)
    data.update(mesh_variables(shown))
    data["model_reference_position"] = _var(("node", "xyz"), mm.model.mesh.nodes, "m",
                                            "gravity-free node position of the identification's mesh at "
                                            "model_mesh R, H (the map moves it to each Λ)")
    ds = xr.Dataset(data, coords=_coordinates(result, postures))
    ds.attrs = provenance("identify", params, config_hash, mesh_level=mesh_level, method=options.method,
                          jacobian_method=options.jacobian, success=int(result.success), message=result.message,
                          noise_model=f"independent relative Gaussian noise, σ = {options.noise}",
                          measurement_set=target.measurement_set, forward_solves=result.forward_solves,
                          failed_solves=result.failed_solves, jacobian_rank=rank, condition_number=cond,
                          branch_restarts=result.branch_restarts, branch_drift=result.branch_drift,
                          iterations=result.iterations, verdict=verdict.verdict, verdict_message=verdict.message,
                          fit_statistic=verdict.statistic, fit_threshold=verdict.threshold, fit_dof=verdict.dof,
                          worst_measurements=[name for name, _ in verdict.worst], input_notes=list(target.notes),
                          regime_warning=shape_warning(params, [result.solutions[p] for p in postures]),
                          model_mesh={"R": mm.model.mesh.R, "H": mm.model.mesh.H},
                          title="breastcore parameter identification", **problem.attrs())
    return ds


def _history_variables(result):
    """Per accepted iteration: parameters, cost, measurement errors, wall time."""
    return {
        "parameters": _var(("iteration", "parameter"), np.array(result.parameters), PARAMETER_UNIT_LIST,
                           "parameter values per accepted iteration; units per parameter in parameter_units"),
        "cost": _var(("iteration",), np.array(result.cost), "1", "cost E = Σ w (M/M̄ − 1)²"),
        "measurement_error": _var(("iteration", "posture", "quantity"), np.array(result.measurement_error), "1",
                                  "relative measurement error M(Λ)/M̄ − 1"),
        "wall_time": _var(("iteration",), np.array(result.wall_time), "s", "wall time since the start"),
    }


def _uncertainty_variables(estimate, cov_log, low, high, noise):
    """The linearised covariance, the 95 % intervals and which parameters they determine."""
    return {
        "log_covariance": _var(("parameter", "parameter_"), cov_log, "1",
                               f"covariance of ln Λ under {noise:.0%} relative 1σ measurement noise"),
        "covariance": _var(("parameter", "parameter_"), cov_log * np.outer(estimate, estimate),
                           "products of parameter_units", "covariance of Λ (linearised)"),
        "interval_low": _var(("parameter",), low, PARAMETER_UNIT_LIST,
                             f"lower bound of the {Z95:.2f}σ (95 %) interval "
                             "(NaN where the parameter is not determined)"),
        "interval_high": _var(("parameter",), high, PARAMETER_UNIT_LIST,
                              f"upper bound of the {Z95:.2f}σ (95 %) interval "
                              "(NaN where the parameter is not determined)"),
        "interval_decades": _var(("parameter",), interval_decades(cov_log), "1",
                                 "width of the 95 % interval, log10(high / low)"),
        "determined": _var(("parameter",), determined(cov_log).astype(np.int8), "1",
                           f"1 if the 95 % interval spans at most a factor {DETERMINED_FACTOR:g}; 0: not determined "
                           "by these measurements"),
    }


def _coordinates(result, postures):
    """The dimensions' coordinates: the mesh's, then parameter, posture, quantity, iteration."""
    coords = mesh_coords()
    coords.update({
        "parameter": _var(("parameter",), np.array(IDENTIFIED), "1", "identified parameter"),
        "parameter_": _var(("parameter_",), np.array(IDENTIFIED), "1", "identified parameter (second axis)"),
        "parameter_units": _var(("parameter",), np.array([PARAMETER_INFO[p].units for p in IDENTIFIED]), "1",
                                "unit of each parameter"),
        "posture": _var(("posture",), np.array(postures), "1", "posture name"),
        "quantity": _var(("quantity",), np.array(QUANTITIES), "1", "measured quantity"),
        "iteration": _var(("iteration",), np.arange(len(result.cost)), "1", "accepted iteration (0 = initial)"),
    })
    return coords


def verdict_of(result, target, noise):
    """The :class:`~breastcore.inverse.verdict.FitVerdict` of an identification result against its data."""
    labels = [f"{p.name}:{q}" for p in target.postures for q in QUANTITIES]
    return fit_verdict(result.success, result.measurement_error[-1], target.weights, noise, labels)
