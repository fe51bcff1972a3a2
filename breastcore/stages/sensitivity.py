"""Stage ``sensitivity``: the linearised and (optionally) the paper's finite sensitivity of an identification."""

from __future__ import annotations

from breastcore.inverse.sensitivity import finite_sensitivity, sensitivity_dataset
from breastcore.inverse.uncertainty import linearised_sensitivity
from breastcore.io.datasets import open_dataset, write_netcdf
from breastcore.io.rebuild import problem_from_identification


def run_sensitivity(spec, identify_path, out, config_hash=None, processes=1):
    """Both matrices of the identification at ``identify_path``, on exactly its problem (constants,
    solver, options, mesh), which the identification dataset records."""
    ds = open_dataset(identify_path)
    problem, mm, target, estimate = problem_from_identification(ds)
    J = ds["jacobian"].values.reshape(-1, ds.sizes["parameter"])
    linear = linearised_sensitivity(J, target.weights)
    finite, failures, limited = (None, 0, 0)
    if spec["finite"]:
        finite, failures, limited = finite_sensitivity(mm, target, estimate, problem.identification, spec["delta"],
                                                       processes)
    write_netcdf(sensitivity_dataset(ds, finite, linear, failures, spec["delta"], config_hash, limited), out)
