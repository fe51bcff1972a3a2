"""Stage ``stability``: one chunk of a stability grid; every case ends in a recorded outcome."""

from __future__ import annotations

import logging

from breastcore.forward.options import SolverOptions
from breastcore.io.datasets import mesh_from_dataset, open_dataset, write_netcdf
from breastcore.model.parameters import Parameters
from breastcore.model.postures import parse_posture
from breastcore.problem import ProblemSpec
from breastcore.studies.stability import run_case, stability_dataset

log = logging.getLogger(__name__)


def run_stability(spec, mesh_path, out, config_hash=None):
    """Solve every case of the chunk (the job never fails on a case)."""
    postures = tuple(dict.fromkeys(parse_posture(str(case["posture"])) for case in spec["cases"]))
    problem = ProblemSpec(parameters=Parameters(**spec["constants"]), solver=SolverOptions(**spec["solver"]),
                          postures=postures)
    model = problem.forward_model(mesh_from_dataset(open_dataset(mesh_path)))
    outcomes, records, messages = [], [], []
    for i, case in enumerate(spec["cases"]):
        outcome, record, message = run_case(model, case, problem.parameters)
        log.info("case %d/%d %s: %s %s", i + 1, len(spec["cases"]), case, outcome, message)
        outcomes.append(outcome)
        records.append(record)
        messages.append(message)
    write_netcdf(stability_dataset(spec["cases"], outcomes, records, messages, spec["level"], problem, config_hash),
                 out)
