"""Identification from extreme initial guesses: part of the stability scene (issue #5).

Each run starts from the paper's Λ̄ with moduli scaled by an extreme factor
(×0.25 or ×4: each modulus alone, then all four together) and identifies on
inverse-crime data (the same mesh, at Λ̄). A run never raises: it ends as
``recovered`` (every parameter within :data:`RECOVERED_TOL`), ``wrong_minimum``
(converged elsewhere), ``not_converged``, ``solve_error`` (the forward solve at
the guess failed: the typed error) or ``crash`` (any other exception).
"""

from __future__ import annotations

import logging
import time

import numpy as np
import xarray as xr

from breastcore.forward.options import SolverOptions
from breastcore.forward.records import SolveError
from breastcore.inverse.identify import identify
from breastcore.inverse.operator import MeasurementModel
from breastcore.inverse.options import IdentificationOptions
from breastcore.io.datasets import PARAMETER_UNIT_LIST, _var, provenance
from breastcore.model.parameters import IDENTIFIED, Parameters
from breastcore.model.postures import paper_postures
from breastcore.problem import ProblemSpec

log = logging.getLogger(__name__)

OUTCOMES = ("recovered", "wrong_minimum", "not_converged", "solve_error", "crash")
MODULI = IDENTIFIED[2:]
#: Largest |estimate/truth − 1| of a recovered run.
RECOVERED_TOL = 1e-4


def extreme_guesses(factors=(0.25, 4.0)):
    """``[(label, (6,) multipliers of Λ̄)]``: each modulus alone, then all four, per factor."""
    out = []
    for f in factors:
        for k, name in enumerate(MODULI):
            scale = np.ones(len(IDENTIFIED))
            scale[2 + k] = f
            out.append((f"{name} x{f:g}", scale))
        scale = np.ones(len(IDENTIFIED))
        scale[2:] = f
        out.append((f"all moduli x{f:g}", scale))
    return out


def run_guess(mm, target, truth, start, options=IdentificationOptions()):
    """Identify from ``start``; returns ``(outcome, record, message)`` and never raises."""
    tic = time.perf_counter()
    record = {"iterations": np.nan, "cost": np.nan, "max_error": np.nan, "wall_time": np.nan}
    try:
        result = identify(mm, target, start, options)
    except SolveError as err:
        record["wall_time"] = time.perf_counter() - tic
        return "solve_error", record, str(err)
    except Exception as err:  # noqa: BLE001 — a crash is an outcome to record
        record["wall_time"] = time.perf_counter() - tic
        return "crash", record, f"{type(err).__name__}: {err}"
    error = float(np.abs(result.estimate / truth - 1.0).max())
    record.update(iterations=len(result.cost) - 1, cost=result.cost[-1], max_error=error,
                  wall_time=time.perf_counter() - tic)
    if not np.isfinite(error):
        return "crash", record, "non-finite estimate"
    if error <= RECOVERED_TOL:
        return "recovered", record, result.message
    return ("wrong_minimum" if result.success else "not_converged"), record, result.message


def extreme_guess_dataset(labels, starts, outcomes, records, messages, level, problem, config_hash=None) -> xr.Dataset:
    """The outcome of every guess; ``problem`` (the truth Λ̄, constants, solver, options) is stored as ``problem``."""
    units = {"iterations": ("1", "accepted identification iterations"), "cost": ("1", "final cost E"),
             "max_error": ("1", "largest |estimate / truth − 1| over the six parameters"),
             "wall_time": ("s", "wall time of the identification")}
    data = {"guess_label": _var(("guess",), np.array(labels), "1", "which moduli were scaled, and by what"),
            "guess": _var(("guess", "parameter"), np.array(starts), PARAMETER_UNIT_LIST, "initial guess"),
            "guess_outcome": _var(("guess",), np.array(outcomes), "1", f"one of {', '.join(OUTCOMES)}"),
            "guess_message": _var(("guess",), np.array(messages), "1", "stopping message or failure diagnostics")}
    for name, (u, long_name) in units.items():
        data["guess_" + name] = _var(("guess",), np.array([r[name] for r in records], float), u, long_name)
    coords = {"parameter": _var(("parameter",), np.array(IDENTIFIED), "1", "identified parameter")}
    counts = {o: int(sum(x == o for x in outcomes)) for o in OUTCOMES}
    ds = xr.Dataset(data, coords=coords)
    ds.attrs = provenance("extreme", problem.parameters, config_hash, mesh_level=level, guess_outcome_counts=counts,
                          title=f"identification from extreme guesses on the {level} mesh", **problem.attrs())
    return ds


def extreme_guess_study(spec, mesh, config_hash=None) -> xr.Dataset:
    """Run every guess of a workflow job ``spec`` (``factors``, ``level``, ``constants``, ``solver``)."""
    problem = ProblemSpec(parameters=Parameters(**spec["constants"]), solver=SolverOptions(**spec["solver"]),
                          postures=paper_postures(), measurement_set="paper15",
                          identification=IdentificationOptions(**spec["identification"]))
    model = problem.forward_model(mesh)
    truth = np.array(problem.parameters.identified())
    truth_model = MeasurementModel.from_problem(problem, model=model)
    target = truth_model.measure(truth_model.solve(truth))
    options = problem.identification
    labels, starts, runs = [], [], []
    for label, scale in extreme_guesses(spec["factors"]):
        mm = MeasurementModel.from_problem(problem, model=model)   # no warm starts carried between runs
        runs.append(run_guess(mm, target, truth, truth * scale, options))
        log.info("guess %s: %s (%s)", label, runs[-1][0], runs[-1][2])
        labels.append(label)
        starts.append(truth * scale)
    outcomes, records, messages = (list(column) for column in zip(*runs))
    return extreme_guess_dataset(labels, starts, outcomes, records, messages, spec["level"], problem, config_hash)
