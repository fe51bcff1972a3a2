"""Stage ``measure``: synthetic measurements of a solution (optionally noisy), or a patient's values."""

from __future__ import annotations

import logging

import numpy as np

from breastcore.io.datasets import open_dataset, write_netcdf
from breastcore.io.patient import PatientMeasurements, patient_from_dict
from breastcore.io.targets import measure_solution, measurement_dataset
from breastcore.problem import ProblemSpec

log = logging.getLogger(__name__)


def run_measure(spec, solution_path, out, config_hash=None):
    """A patient's values (``spec["patient"]``), or the solution's measurements with its problem spec."""
    if "patient" in spec:
        p = spec["patient"]
        target = patient_from_dict({"measurement_set": p["measurement_set"], "units": p["units"],
                                    "postures": p["postures"]}, allow_implausible=p.get("allow_implausible", False))
        for note in target.notes:
            log.warning("patient input: %s", note)
        write_netcdf(measurement_dataset(target, "patient", config_hash=config_hash), out)
        return
    solution = open_dataset(solution_path)
    target, marks = measure_solution(solution, spec["measurement_set"])
    if spec.get("noise", 0) > 0:
        rng = np.random.default_rng(spec["seed"])
        noisy = target.values * (1 + rng.uniform(-spec["noise"], spec["noise"], target.values.shape))
        target = PatientMeasurements(target.postures, target.quantities, noisy, target.measurement_set)
    problem = ProblemSpec.from_dataset(solution).replace(measurement_set=target.measurement_set)
    write_netcdf(measurement_dataset(target, str(solution_path), landmarks=marks, problem=problem,
                                     config_hash=config_hash), out)
