"""Stability studies: solve a grid of stiff and extreme cases and record every outcome.

A case never raises: it ends as ``converged`` (and independently verified),
``unverified``, ``nan``, ``solve_error`` (the typed failure, with its diagnostics)
or ``crash`` (any other exception, recorded with its message).
"""

from __future__ import annotations

import itertools
import time

import numpy as np
import xarray as xr

from breastcore.forward.model import ForwardModel
from breastcore.forward.records import SolveError
from breastcore.io.datasets import _var, provenance
from breastcore.model.parameters import Parameters
from breastcore.model.postures import parse_posture

OUTCOMES = ("converged", "unverified", "nan", "solve_error", "crash")
#: Grid factors: λ/μ, μ (Pa), μ_s (Pa, λ_s = 5 μ_s as in Λ̄), H/R, c (Pa), δ (m), posture.
FACTORS = ("lam_over_mu", "mu", "mu_s", "H_over_R", "c", "delta", "posture")
RECORDS = {
    "iterations": ("1", "minimiser iterations"),
    "continuation_steps": ("1", "continuation steps"),
    "gradient_norm": ("N", "final free-dof gradient norm"),
    "tolerance": ("N", "stopping tolerance"),
    "min_det_F": ("1", "smallest det F"),
    "max_stretch": ("1", "largest principal stretch"),
    "energy": ("J", "energy at the end"),
    "torso_penetration": ("m", "largest depth of a node behind the torso plane y = 0"),
    "load_factor": ("1", "gravity fraction reached"),
    "wall_time": ("s", "wall time of the case"),
}


def grid_cases(grid, sample=0, seed=0):
    """Every combination of ``grid`` (dict factor → values), or a fixed-seed subsample.

    The subsample gives each factor a column in which its values are repeated evenly
    and permuted, so that every value appears (about ``sample / k`` times).
    """
    names = list(FACTORS)
    if not sample:
        return [dict(zip(names, v)) for v in itertools.product(*(grid[n] for n in names))]
    rng = np.random.default_rng(seed)
    cols = {n: [grid[n][i % len(grid[n])] for i in rng.permutation(sample)] for n in names}
    cases = [{n: cols[n][i] for n in names} for i in range(sample)]
    unique = {tuple(c[n] for n in names): c for c in cases}
    return list(unique.values())


def case_parameters(case, base: Parameters, R=0.0562):
    mu, mu_s = float(case["mu"]), float(case["mu_s"])
    return base.replace(R=R, H=float(case["H_over_R"]) * R, lambda_breast=float(case["lam_over_mu"]) * mu,
                        mu_breast=mu, lambda_skin=5.0 * mu_s, mu_skin=mu_s, chassaignac=float(case["c"]),
                        smoothing=float(case["delta"]))


def run_case(model: ForwardModel, case, base=Parameters()):
    """Solve one case; returns ``(outcome, record dict, message)``; never raises."""
    record = dict.fromkeys(RECORDS, np.nan)
    tic = time.perf_counter()
    try:
        params = case_parameters(case, base)
        posture = parse_posture(str(case["posture"]))
        sol = model.solve(params, posture)
    except SolveError as err:
        record.update(iterations=err.iterations, gradient_norm=err.gradient_norm, tolerance=err.tolerance,
                      min_det_F=err.min_det_F, load_factor=err.load_factor, wall_time=time.perf_counter() - tic)
        return "solve_error", record, str(err)
    except Exception as err:  # noqa: BLE001 — a crash is an outcome to record
        record["wall_time"] = time.perf_counter() - tic
        return "crash", record, f"{type(err).__name__}: {err}"
    record.update(iterations=sol.iterations, continuation_steps=sol.continuation_steps,
                  gradient_norm=sol.gradient_norm, tolerance=sol.tolerance, min_det_F=sol.min_det_F,
                  max_stretch=sol.max_stretch, energy=sol.energy, torso_penetration=sol.torso_penetration,
                  load_factor=1.0, wall_time=sol.wall_time)
    if not (np.all(np.isfinite(sol.position)) and np.isfinite([sol.energy, sol.gradient_norm]).all()):
        return "nan", record, "non-finite solution"
    problem = model.problem(params, posture)                 # independent re-evaluation of the residual
    g = float(np.linalg.norm(problem.gradient(problem.free(sol.position))))
    ok = g <= sol.tolerance and problem.bulk.det_F(sol.position).min() > 0
    return ("converged" if ok else "unverified"), record, "" if ok else f"recomputed |g| = {g:.3e} N"


def stability_dataset(cases, outcomes, records, messages, level, problem, config_hash=None) -> xr.Dataset:
    """The outcomes of a chunk of cases. ``problem``: the base problem spec (constants and
    solver; each case's Λ, c, δ and posture are in its variables), stored as ``problem``."""
    data = {name: _var(("case",), np.array([c[name] for c in cases]), "1" if name != "posture" else "1",
                       f"grid factor {name}") for name in FACTORS}
    data["outcome"] = _var(("case",), np.array(outcomes), "1", f"one of {', '.join(OUTCOMES)}")
    data["message"] = _var(("case",), np.array(messages), "1", "failure diagnostics")
    for name, (units, long_name) in RECORDS.items():
        data[name] = _var(("case",), np.array([r[name] for r in records], float), units, long_name)
    for name, units in (("mu", "Pa"), ("mu_s", "Pa"), ("c", "Pa"), ("delta", "m")):
        data[name].attrs["units"] = units
    ds = xr.Dataset(data)
    counts = {o: int(sum(x == o for x in outcomes)) for o in OUTCOMES}
    ds.attrs = provenance("stability", None, config_hash, mesh_level=level, outcome_counts=counts,
                          convergence_rate=counts["converged"] / max(len(cases), 1),
                          title=f"stability grid on the {level} mesh", **problem.attrs())
    return ds
