"""Helpers of the identification benchmark (``bench_identify.py``).

Everything here is deterministic: fixed starts. A run gets a fresh
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
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures

#: The paper's reference Λ̄ (SI).
TRUTH = np.array(Parameters().identified())
PAPER_TIME = {"coarse": 196.0, "ultra-thin": 1587.0}          # s, Intel i5-2450M

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


def truth_measurements(level: str) -> np.ndarray:
    """``M(Λ̄)``, (posture, quantity), from a cold Newton solve on ``level``."""
    mm = measurement_model(level)
    return mm.measure(mm.solve(TRUTH))


def options(method: str = "lm", jacobian: str = "implicit", **kw) -> IdentificationOptions:
    return IdentificationOptions(method=method, jacobian=jacobian, **kw)


def run(level: str, target, start, opts: IdentificationOptions, solver: str = "newton",
        processes: int = 1) -> dict:
    """One identification from ``start``; the outcome as a JSON-able dict.

    ``time`` is the wall time of the whole :func:`identify` call (initial solve and
    the final Jacobian included; with ``processes > 1`` the workers' fork, not their shutdown).
    ``forward_solves`` counts posture solves (one evaluation of Λ solves three postures), as
    ``IdentificationResult`` does.
    ``processes``: postures solved in this many processes (``MeasurementModel``).
    """
    mm = measurement_model(level, solver, processes)
    tic = time.perf_counter()
    try:
        res = identify(mm, np.asarray(target, float), np.asarray(start, float), opts)
        wall = time.perf_counter() - tic
    except Exception as err:  # noqa: BLE001 — identify raising is a result too (recorded, not fatal)
        return dict(ok=False, success=False, error=repr(err), time=time.perf_counter() - tic,
                    rel_error=[float("nan")] * 6, max_rel_error=float("nan"), iterations=float("nan"),
                    forward_solves=mm.solves, failed_solves=float("nan"), cost=float("nan"),
                    message=f"identify raised {err!r}")
    finally:
        mm.close()                       # after the timing: shutting the workers down is not part of the run
    rel = res.estimate / TRUTH - 1.0
    out = dict(ok=True, success=bool(res.success), message=res.message, time=wall,
               estimate=res.estimate.tolist(), rel_error=rel.tolist(), max_rel_error=float(np.abs(rel).max()),
               iterations=len(res.cost) - 1, forward_solves=int(res.forward_solves),
               failed_solves=int(res.failed_solves), cost=float(res.cost[-1]), cost0=float(res.cost[0]),
               branch_restarts=int(res.branch_restarts), branch_drift=float(res.branch_drift))
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
