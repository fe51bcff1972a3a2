"""Helpers shared by the identification study and benchmark (issue #3).

Everything here is deterministic: fixed seeds, fixed starts. A run gets a fresh
:class:`~breastcore.inverse.operator.MeasurementModel` (sharing the level's
:class:`~breastcore.forward.model.ForwardModel`), so warm starts and the solve counter
never leak from one run into the next.
"""

from __future__ import annotations

import functools
import json
import time

import numpy as np

from breastcore.forward.model import ForwardModel
from breastcore.forward.options import SolverOptions
from breastcore.inverse.identify import identify
from breastcore.inverse.operator import MeasurementModel
from breastcore.inverse.options import IdentificationOptions
from breastcore.inverse.uncertainty import intervals, log_covariance
from breastcore.model.mesh import LEVEL_MESH_SIZE, mesh_cap, mesh_level
from breastcore.model.parameters import IDENTIFIED, Parameters
from breastcore.model.postures import paper_postures

#: The paper's reference Λ̄ (SI).
TRUTH = np.array(Parameters().identified())
NAMES = ("R", "H", "λ", "μ", "λ_s", "μ_s")
#: The paper's Table 1, coarse row: % parameter loss after 25 iterations.
PAPER_TABLE1_COARSE = (0.08, 0.39, 0.42, 0.89, 0.27, 2.77)
PAPER_TIME = {"coarse": 196.0, "ultra-thin": 1587.0}          # s, Intel i5-2450M
PAPER_ANNEX = {"noiseless": 6.4, "noisy": 16.4}                # mean % parameter error, 50 cases
LEVELS = ("coarse", "medium", "medium-thin", "thin", "very-thin", "ultra-thin")

#: Fixed starts 30 % off (every parameter ×0.7 or ×1.3, H < R in each).
STARTS_30 = (
    (1.3, 0.7, 0.7, 1.3, 1.3, 0.7),
    (1.3, 1.3, 1.3, 0.7, 0.7, 1.3),
    (0.7, 0.7, 1.3, 1.3, 0.7, 0.7),
)


@functools.lru_cache(maxsize=None)
def forward_model(level: str, solver: str = "newton") -> ForwardModel:
    """The identification's forward model on a named level (reference cap at Λ̄, mapped smoothly)."""
    return ForwardModel(mesh_level(level), SolverOptions(method=solver))


def measurement_model(level: str, solver: str = "newton", processes: int = 1) -> MeasurementModel:
    """A fresh measurement model (no warm starts, solve counter 0) on ``level``."""
    return MeasurementModel(forward_model(level, solver), Parameters(), paper_postures(), processes=processes)


def truth_measurements(level: str, direct_gmsh: bool = False) -> np.ndarray:
    """``M(Λ̄)``, (posture, quantity), from a cold Newton solve.

    ``direct_gmsh``: on a mesh that gmsh builds for the true (R, H) with the
    level's size (``mesh_cap``), i.e. no inverse crime when the identification uses
    another level.
    """
    if direct_gmsh:
        mesh = mesh_cap(TRUTH[0], TRUTH[1], LEVEL_MESH_SIZE[level])
        mm = MeasurementModel(ForwardModel(mesh), Parameters(), paper_postures())
    else:
        mm = measurement_model(level)
    return mm.measure(mm.solve(TRUTH))


def random_starts(n: int, spread: float, seed: int) -> np.ndarray:
    """``n`` starts, each parameter ``Λ̄ (1 + U(−spread, spread))``, H redrawn until H < R."""
    rng = np.random.default_rng(seed)
    out = np.empty((n, len(TRUTH)))
    for k in range(n):
        f = 1.0 + rng.uniform(-spread, spread, len(TRUTH))
        while not f[1] * TRUTH[1] < f[0] * TRUTH[0]:
            f[1] = 1.0 + rng.uniform(-spread, spread)
        out[k] = TRUTH * f
    return out


def options(method: str = "lm", jacobian: str = "implicit", **kw) -> IdentificationOptions:
    return IdentificationOptions(method=method, jacobian=jacobian, **kw)


def run(level: str, target, start, opts: IdentificationOptions, solver: str = "newton", noise_cov=(),
        processes: int = 1) -> dict:
    """One identification from ``start``; the outcome as a JSON-able dict.

    ``time`` is the wall time of the whole :func:`identify` call (initial solve and
    the final Jacobian included). ``forward_solves`` counts posture solves (one
    evaluation of Λ solves three postures), as ``IdentificationResult`` does.
    ``noise_cov``: 1σ levels at which to build 95 % intervals from the final Jacobian.
    ``processes``: postures solved in this many processes (``MeasurementModel``).
    """
    mm = measurement_model(level, solver, processes)
    tic = time.perf_counter()
    try:
        res = identify(mm, np.asarray(target, float), np.asarray(start, float), opts)
    except Exception as err:  # noqa: BLE001 — identify raising is a result too (recorded, not fatal)
        return dict(ok=False, success=False, error=repr(err), time=time.perf_counter() - tic,
                    rel_error=[float("nan")] * 6, max_rel_error=float("nan"), iterations=float("nan"),
                    forward_solves=mm.solves, failed_solves=float("nan"), cost=float("nan"),
                    message=f"identify raised {err!r}")
    wall = time.perf_counter() - tic
    rel = res.estimate / TRUTH - 1.0
    out = dict(ok=True, success=bool(res.success), message=res.message, time=wall,
               estimate=res.estimate.tolist(), rel_error=rel.tolist(), max_rel_error=float(np.abs(rel).max()),
               iterations=len(res.cost) - 1, forward_solves=int(res.forward_solves),
               failed_solves=int(res.failed_solves), cost=float(res.cost[-1]), cost0=float(res.cost[0]),
               branch_restarts=int(res.branch_restarts), branch_drift=float(res.branch_drift))
    J = res.jacobian.reshape(-1, len(IDENTIFIED))
    for sigma in noise_cov:
        low, high = intervals(res.estimate, log_covariance(J, sigma))
        out[f"covered_{sigma:.6g}"] = ((low <= TRUTH) & (TRUTH <= high)).tolist()
        out[f"halfwidth_{sigma:.6g}"] = (np.log(high / res.estimate)).tolist()
    return out


def child(level, target, start, opts: dict, solver="newton") -> None:
    """Entry point of a time-capped subprocess: print the outcome of :func:`run` as JSON."""
    out = run(level, target, start, IdentificationOptions(**opts), solver)
    print(json.dumps(out), flush=True)


def child_code(level, target, start, opts: IdentificationOptions, solver="newton") -> str:
    """Python source that runs :func:`child` (for ``_common.run_python``)."""
    kw = {k: getattr(opts, k) for k in opts.__dataclass_fields__}
    return (f"from benchmarks._ident import child\n"
            f"child({level!r}, {np.asarray(target).tolist()!r}, {np.asarray(start).tolist()!r}, {kw!r}, "
            f"{solver!r})\n")


def pct(x) -> float:
    return 100.0 * float(x)
