"""Stage ``identify``: Λ from a measurement dataset, with the problem spec it was identified with."""

from __future__ import annotations

import json
import logging

from breastcore.forward.options import SolverOptions
from breastcore.inverse.identify import identify
from breastcore.inverse.operator import MeasurementModel
from breastcore.inverse.options import IdentificationOptions
from breastcore.inverse.uncertainty import UNDETERMINED, UNSEEN, at_limit, undetermined
from breastcore.io.datasets import mesh_from_dataset, open_dataset, write_netcdf
from breastcore.io.identification import identification_dataset
from breastcore.io.targets import target_from_dataset, truth_from_dataset
from breastcore.model.parameters import IDENTIFIED, Parameters
from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.problem import ProblemSpec

log = logging.getLogger(__name__)


def run_identifications(specs, measurements, mesh, outputs, logs, job):
    """The identifications of one workflow job, one after the other, each with its own log.

    Parameters
    ----------
    specs : list of dict
        Identify job specs (:meth:`breastcore.pipeline.plan.Plan.identify`), one per output.
    measurements, mesh : str
        The measurement and mesh datasets they share.
    outputs, logs : list of str
        Each identification's dataset and log file.
    job : str
        The rule that runs them (``identify``, or ``identify_batch_<key>`` for a batch of
        :mod:`breastcore.pipeline.batches`): the first line of each log names it, as
        ``identification <i> of <n> in job <job>``.
    """
    for index, (spec, out, log_path) in enumerate(zip(specs, outputs, logs, strict=True), start=1):
        with log_to(log_path):
            log.info("identification %d of %d in job %s", index, len(specs), job)
            run_identify(spec, measurements, mesh, out, spec_key(spec))


def run_identify(spec, measure_path, mesh_path, out, config_hash=None):
    """Identify Λ; a run that does not converge is still written (success = 0)."""
    ds_m = open_dataset(measure_path)
    target = target_from_dataset(ds_m)
    mesh_ds = open_dataset(mesh_path)
    initial = [float(spec["initial"][k]) for k in IDENTIFIED]
    problem = ProblemSpec(parameters=Parameters(**spec["constants"]).with_identified(initial),
                          solver=SolverOptions(**spec["solver"]), postures=target.postures,
                          measurement_set=target.measurement_set,
                          identification=IdentificationOptions(**spec["identification"]))
    ds = identify_target(problem, mesh_from_dataset(mesh_ds), target, truth_from_dataset(ds_m), initial,
                         mesh_level=mesh_ds.attrs["mesh_level"], config_hash=config_hash)
    write_netcdf(ds, out)
    log_verdict(ds)


def identify_target(problem, mesh, target, truth, initial, *, mesh_level, processes=1, config_hash=None):
    """The identification dataset of ``target`` on ``mesh``: the one path of the workflow and the CLI.

    Parameters
    ----------
    problem : ProblemSpec
        Constants, solver, postures, measurement set and identification options.
    mesh : CapMesh
    target : Target
        The measurements (:func:`~breastcore.io.targets.target_from_dataset`).
    truth : dict or None
        Generating parameters of synthetic measurements (relative errors are stored).
    initial : sequence of 6 float
        Initial guess of the identified parameters, in their units.
    mesh_level : str
        Recorded in the dataset.
    processes : int
        Postures solved in this many processes.
    """
    with MeasurementModel.from_problem(problem, mesh, processes=processes) as mm:     # closes its workers
        result = identify(mm, target.values, initial, problem.identification, target.weights)
        return identification_dataset(result, mm, target, problem, initial=initial,
                                      truth=[truth[k] for k in IDENTIFIED] if truth else None,
                                      mesh_level=mesh_level, config_hash=config_hash)


def log_verdict(ds):
    """One log line with the fit verdict (a warning unless consistent) and the undetermined parameters."""
    level = logging.INFO if ds.attrs["verdict"] == "consistent" else logging.WARNING
    log.log(level, "fit verdict %s: %s; optimiser: %s", ds.attrs["verdict"], ds.attrs["verdict_message"],
            ds.attrs["message"])
    if ds.attrs.get("regime_warning"):
        log.warning("estimate: %s", ds.attrs["regime_warning"])
    for note in json.loads(ds.attrs.get("input_notes", "[]")):
        log.warning("patient input: %s", note)
    loose = undetermined(ds["parameter"].values, ds["determined"].values)
    if loose:
        log.warning("%s: %s", UNDETERMINED, ", ".join(loose))
    ends = at_limit(ds["parameter"].values, ds["limit"].values)
    if ends:
        log.warning("%s: %s", UNSEEN, ", ".join(ends))
