"""One function per workflow stage: read inputs, call breastcore, write one dataset.

The Snakemake scripts in ``workflow/scripts`` are thin wrappers around these, so
every stage can also be run (and tested) without Snakemake.
"""

from __future__ import annotations

import logging

import numpy as np

from .datasets import mesh_dataset, mesh_from_dataset, open_dataset, parameters_from_dataset, write_netcdf
from .forward import ForwardModel, SolverOptions
from .identification_dataset import identification_dataset
from .identify import IdentificationOptions, identify
from .mesh import LEVEL_MESH_SIZE, R0, H0, mesh_cap, refold
from .observation import MeasurementModel
from .parameters import IDENTIFIED, Parameters
from .patient import PatientMeasurements, patient_from_dict
from .postures import Posture
from .sensitivity import finite_sensitivity, sensitivity_dataset
from .solution import solution_dataset, solve_postures
from .study import problem_from_identification
from .targets import measure_solution, measurement_dataset, target_from_dataset, truth_from_dataset
from .uncertainty import linearised_sensitivity

log = logging.getLogger(__name__)


def run_mesh(spec, out, config_hash=None):
    """Level mesh at the paper's (R, H), or a direct gmsh mesh at a given (R, H)."""
    level = spec["level"]
    R, H = spec.get("R", R0), spec.get("H", H0)
    mesh = mesh_cap(R, H, LEVEL_MESH_SIZE[level], spec.get("fold_angle", 180.0))
    write_netcdf(mesh_dataset(mesh, level, LEVEL_MESH_SIZE[level], config_hash), out)
    log.info("mesh %s: %d nodes, %d tets", level, len(mesh.nodes), len(mesh.tets))


def run_solve(spec, mesh_path, out, config_hash=None):
    mesh_ds = open_dataset(mesh_path)
    mesh = mesh_from_dataset(mesh_ds)
    params = Parameters(**spec["parameters"])
    postures = [Posture(p["name"], p["angle"]) for p in spec["postures"]]
    options = SolverOptions(**spec["solver"])
    model = ForwardModel(mesh, options)
    solutions = solve_postures(model, params, postures)
    shown = refold(model.map.mesh_at(params.R, params.H), params.fold_angle)
    write_netcdf(solution_dataset(shown, params, solutions, options, mesh_level=mesh_ds.attrs["mesh_level"],
                                  config_hash=config_hash), out)


def run_measure(spec, solution_path, out, config_hash=None):
    """Synthetic measurements of a solution (optionally noisy), or a patient's values."""
    if "patient" in spec:
        p = spec["patient"]
        target = patient_from_dict({"measurement_set": p["measurement_set"], "units": p["units"],
                                    "postures": p["postures"]})
        write_netcdf(measurement_dataset(target, "patient", config_hash=config_hash), out)
        return
    solution = open_dataset(solution_path)
    target, marks = measure_solution(solution, spec["measurement_set"])
    if spec.get("noise", 0) > 0:
        rng = np.random.default_rng(spec["seed"])
        noisy = target.values * (1 + rng.uniform(-spec["noise"], spec["noise"], target.values.shape))
        target = PatientMeasurements(target.postures, target.quantities, noisy, target.measurement_set)
    write_netcdf(measurement_dataset(target, solution_path, landmarks=marks, truth=parameters_from_dataset(solution),
                                     config_hash=config_hash), out)


def run_identify(spec, measure_path, mesh_path, out, config_hash=None):
    """Identify Λ; a run that does not converge is still written (success = 0)."""
    ds_m = open_dataset(measure_path)
    target = target_from_dataset(ds_m)
    mesh_ds = open_dataset(mesh_path)
    initial = [float(spec["initial"][k]) for k in IDENTIFIED]
    base = Parameters(**spec["constants"]).with_identified(initial)
    options = IdentificationOptions(**spec["identification"])
    model = ForwardModel(mesh_from_dataset(mesh_ds), SolverOptions(**spec["solver"]))
    mm = MeasurementModel(model, base, target.postures, target.measurement_set)
    result = identify(mm, target.values, initial, options, target.weights)
    truth = truth_from_dataset(ds_m)
    ds = identification_dataset(result, mm, target, options, initial=initial,
                                truth=[truth[k] for k in IDENTIFIED] if truth else None,
                                mesh_level=mesh_ds.attrs["mesh_level"], config_hash=config_hash)
    write_netcdf(ds, out)
    if not result.success:
        log.warning("identification did not converge: %s", result.message)


def run_sensitivity(spec, identify_path, out, config_hash=None, processes=1):
    ds = open_dataset(identify_path)
    mm, target, options, estimate = problem_from_identification(ds)
    J = ds["jacobian"].values.reshape(-1, ds.sizes["parameter"])
    linear = linearised_sensitivity(J, target.weights)
    finite, failures, limited = (None, 0, 0)
    if spec["finite"]:
        finite, failures, limited = finite_sensitivity(mm, target, estimate, options, spec["delta"], processes)
    write_netcdf(sensitivity_dataset(ds, finite, linear, failures, spec["delta"], config_hash, limited), out)


def run_stability(spec, mesh_path, out, config_hash=None):
    """Solve every case of the chunk; each ends in a recorded outcome (the job never fails on a case)."""
    from .stability import run_case, stability_dataset
    model = ForwardModel(mesh_from_dataset(open_dataset(mesh_path)), SolverOptions(**spec["solver"]))
    base = Parameters(**spec["constants"])
    outcomes, records, messages = [], [], []
    for i, case in enumerate(spec["cases"]):
        outcome, record, message = run_case(model, case, base)
        log.info("case %d/%d %s: %s %s", i + 1, len(spec["cases"]), case, outcome, message)
        outcomes.append(outcome)
        records.append(record)
        messages.append(message)
    write_netcdf(stability_dataset(spec["cases"], outcomes, records, messages, spec["level"], config_hash), out)


def run_extreme_guesses(spec, mesh_path, out, config_hash=None):
    """Identify from every extreme guess on inverse-crime data; each ends in a recorded outcome."""
    from .extreme_guesses import extreme_guess_study
    write_netcdf(extreme_guess_study(spec, mesh_from_dataset(open_dataset(mesh_path)), config_hash), out)
