"""The measurement dataset: ``measurement(posture, quantity)`` from a solution or a patient.

Units differ along ``quantity`` (m³, m², m, m, m); each quantity's unit is in the
``quantity_units`` coordinate and in the variable's ``units`` attribute as a list.
"""

from __future__ import annotations

import json

import numpy as np
import xarray as xr

from breastcore.inverse.measurements import LONG_NAMES, QUANTITIES, UNITS, landmark_positions, measure
from breastcore.io.datasets import LANDMARKS, QUANTITY_UNIT_LIST, _var, mesh_from_dataset, provenance
from breastcore.io.patient import PatientMeasurements
from breastcore.io.solution import postures_from_dataset
from breastcore.problem import ProblemSpec

def measurement_dataset(target: PatientMeasurements, source: str, *, landmarks=None, problem=None,
                        config_hash=None) -> xr.Dataset:
    """Dataset of measured (or synthetic) values in SI units.

    Parameters
    ----------
    target : PatientMeasurements
    source : str
        ``"patient"`` or the solution file the values were measured on.
    landmarks : (posture, landmark, xyz) array, optional
        Deformed landmark positions used by the formulas, m.
    problem : ProblemSpec, optional
        The problem whose solution generated synthetic data (attribute ``problem``;
        its parameters, the truth, also in ``parameters``). None for a patient.
    """
    if problem is not None and (problem.measurement_set != target.measurement_set
                                or problem.postures != tuple(target.postures)):
        raise ValueError("the problem spec's measurement set and postures must be those of the measurements")
    truth = None if problem is None else problem.parameters
    data = {
        "measurement": _var(("posture", "quantity"), target.values, QUANTITY_UNIT_LIST,
                            "measured value; units per quantity in quantity_units"),
        "weight": _var(("posture", "quantity"), target.weights, "1", "weight w_i of the measurement in the cost"),
        "posture_angle": _var(("posture",), np.array([p.angle for p in target.postures]), "degree",
                              "forward-bend angle θ"),
    }
    if landmarks is not None:
        data["landmark_position"] = _var(("posture", "landmark", "xyz"), landmarks, "m",
                                         "deformed landmark position used by the formulas")
    coords = {
        "posture": _var(("posture",), np.array([p.name for p in target.postures]), "1", "posture name"),
        "quantity": _var(("quantity",), np.array(QUANTITIES), "1", "measured quantity"),
        "quantity_units": _var(("quantity",), np.array([UNITS[q] for q in QUANTITIES]), "1", "unit of each quantity"),
        "quantity_long_name": _var(("quantity",), np.array([LONG_NAMES[q] for q in QUANTITIES]), "1",
                                   "description of each quantity"),
    }
    if landmarks is not None:
        coords["landmark"] = _var(("landmark",), np.array(LANDMARKS), "1", "landmark name")
        coords["xyz"] = _var(("xyz",), np.array(["x", "y", "z"]), "1", "torso axis")
    ds = xr.Dataset(data, coords=coords)
    ds.attrs = provenance("measure", truth, config_hash, measurement_set=target.measurement_set, source=source,
                          synthetic=int(truth is not None), title="breastcore measurements per posture",
                          input_notes=list(target.notes),
                          **({} if problem is None else problem.attrs()))
    return ds


def target_from_dataset(ds: xr.Dataset) -> PatientMeasurements:
    """The measurements of a measurement dataset, validated again."""
    postures = tuple(postures_from_dataset(ds))
    return PatientMeasurements(postures, QUANTITIES, ds["measurement"].transpose("posture", "quantity").values,
                               ds.attrs["measurement_set"], ds["weight"].values,
                               tuple(json.loads(ds.attrs.get("input_notes", "[]"))))


def truth_from_dataset(ds: xr.Dataset):
    """The generating parameters of synthetic data (dict), or None."""
    return ProblemSpec.from_dataset(ds).parameters.as_dict() if int(ds.attrs.get("synthetic", 0)) else None


def measure_solution(solution: xr.Dataset, measurement_set="paper15"):
    """Measure every posture of a solution dataset: (PatientMeasurements, landmarks array)."""
    mesh = mesh_from_dataset(solution)
    postures = postures_from_dataset(solution)
    values, marks = [], []
    for p in postures:
        x = solution["position"].sel(posture=p.name).values
        m = measure(mesh, x, measurement_set)
        values.append([m[q] for q in QUANTITIES])
        lm = landmark_positions(mesh, x)
        marks.append([lm[k] for k in LANDMARKS])
    return PatientMeasurements(tuple(postures), QUANTITIES, np.array(values), measurement_set), np.array(marks)
