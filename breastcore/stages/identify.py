"""Stage ``identify``: Λ from a measurement dataset, with the problem spec it was identified with."""

from __future__ import annotations

import json
import logging

from ..datasets import mesh_from_dataset, open_dataset, write_netcdf
from ..forward import SolverOptions
from ..identification_dataset import identification_dataset
from ..identification_options import IdentificationOptions
from ..identify import identify
from ..observation import MeasurementModel
from ..parameters import IDENTIFIED, Parameters
from ..problem import ProblemSpec
from ..targets import target_from_dataset, truth_from_dataset
from ..uncertainty import UNDETERMINED, undetermined

log = logging.getLogger(__name__)


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
    mm = MeasurementModel.from_problem(problem, mesh_from_dataset(mesh_ds))
    result = identify(mm, target.values, initial, problem.identification, target.weights)
    truth = truth_from_dataset(ds_m)
    ds = identification_dataset(result, mm, target, problem, initial=initial,
                                truth=[truth[k] for k in IDENTIFIED] if truth else None,
                                mesh_level=mesh_ds.attrs["mesh_level"], config_hash=config_hash)
    write_netcdf(ds, out)
    log_verdict(ds)


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
