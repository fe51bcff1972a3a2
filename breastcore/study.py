"""Rebuild an identification problem from its dataset (for sensitivity and studies)."""

from __future__ import annotations

import json

import numpy as np

from .datasets import mesh_from_dataset, parameters_from_dataset
from .forward import ForwardModel
from .identify import IdentificationOptions
from .measure import QUANTITIES
from .observation import MeasurementModel
from .patient import PatientMeasurements
from .postures import Posture


def problem_from_identification(ds):
    """``(MeasurementModel, target, options, estimate)`` of an identification dataset."""
    options = IdentificationOptions(**json.loads(ds.attrs["options"]))
    postures = tuple(Posture(str(n), float(a)) for n, a in zip(ds["posture"].values, ds["posture_angle"].values))
    target = PatientMeasurements(postures, QUANTITIES, ds["target"].values, ds.attrs["measurement_set"],
                                 ds["weight"].values)
    model = ForwardModel(mesh_from_dataset(ds))
    mm = MeasurementModel(model, parameters_from_dataset(ds), postures, target.measurement_set)
    return mm, target, options, np.asarray(ds["estimate"].values, float)
