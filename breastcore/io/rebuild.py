"""Rebuild an identification problem from its dataset (for sensitivity and studies)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from breastcore.inverse.measurements import QUANTITIES
from breastcore.inverse.operator import MeasurementModel
from breastcore.io.datasets import mesh_from_dataset
from breastcore.io.patient import PatientMeasurements
from breastcore.problem import ProblemSpec, ProblemSpecError


def model_mesh_from_identification(ds):
    """The fixed-topology mesh the identification ran on, node for node.

    The dataset's ``reference_position`` is that mesh moved to the estimate's
    ``(R, H)`` (for display); ``model_reference_position`` keeps the model's own
    nodes, so that a later stage solves on exactly the same mesh, not on one
    mapped there and back (round-off can switch the standing posture's branch).
    """
    if "model_reference_position" not in ds or "model_mesh" not in ds.attrs:
        raise ProblemSpecError("identification dataset without its model mesh (model_reference_position); "
                               "recompute it")
    shape = json.loads(ds.attrs["model_mesh"])            # the fold is the dataset's (refolded to θ_D)
    return dataclasses.replace(mesh_from_dataset(ds), nodes=ds["model_reference_position"].values,
                               R=float(shape["R"]), H=float(shape["H"]))


def problem_from_identification(ds, processes=1):
    """``(ProblemSpec, MeasurementModel, target, estimate)`` of an identification dataset.

    Everything comes from the dataset: the problem spec it was identified with
    (constants, solver, postures, measurement set, options), its mesh, data and weights.
    """
    problem = ProblemSpec.from_dataset(ds)
    target = PatientMeasurements(problem.postures, QUANTITIES, ds["target"].values, problem.measurement_set,
                                 ds["weight"].values)
    mm = MeasurementModel.from_problem(problem, model_mesh_from_identification(ds), processes=processes)
    return problem, mm, target, np.asarray(ds["estimate"].values, float)
