"""An identification's record: the run's history while it goes, and its frozen result."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

log = logging.getLogger("breastcore.inverse.identify")       # one logger for the whole identification


@dataclass(frozen=True)
class IdentificationResult:
    """History and outcome of one identification. Parameters in SI units.

    Attributes
    ----------
    success : bool
        The method's own convergence test (see ``message``); the fit verdict
        (:mod:`~breastcore.inverse.verdict`) says what the estimate is worth.
    message : str
        Why the run stopped.
    estimate : (6,) array
        Λ at the last recorded iteration.
    parameters, cost, measurement_error, wall_time : tuple
        Per recorded iteration: Λ (6,), E, ``M/M̄ − 1`` (posture, quantity), s since the start.
    jacobian : (posture, quantity, 6) array
        ``∂(M/M̄)/∂ln Λ`` at the estimate.
    solutions : dict
        The equilibria at the estimate, by posture name.
    forward_solves, failed_solves : int
        Posture solves, and evaluations of Λ whose solve failed (rejected steps).
    branch_restarts : int
        Runs continued from cold equilibria after a branch drift (:mod:`~breastcore.inverse.branch`).
    branch_drift : float
        ``max |M_warm/M_cold − 1|`` at the last branch check.
    iterations : int
        Accepted steps over all runs.
    """

    success: bool
    message: str
    estimate: np.ndarray
    parameters: tuple
    cost: tuple
    measurement_error: tuple
    wall_time: tuple
    jacobian: np.ndarray
    solutions: dict
    forward_solves: int
    failed_solves: int
    branch_restarts: int
    branch_drift: float
    iterations: int


class IdentificationRun:
    """What one identification has done so far (the methods and the branch check add to it).

    ``record(values, solutions)`` appends an iteration; the other attributes are the fields
    of :class:`IdentificationResult` that the run fills in as it goes.
    """

    def __init__(self, mm, target, weights):
        self.mm, self.target, self.weights = mm, np.asarray(target, float), np.asarray(weights, float)
        self.tic = time.perf_counter()
        self.success, self.message = False, ""
        self.parameters, self.cost, self.measurement_error, self.wall_time = [], [], [], []
        self.solutions = None
        self.failed_solves = self.branch_restarts = self.iterations = 0
        self.branch_drift = 0.0

    def record(self, values, solutions):
        """Append the iteration at ``Λ = values`` with equilibria ``solutions``."""
        error = self.mm.measure(solutions) / self.target - 1.0
        self.parameters.append(np.array(values, float))
        self.measurement_error.append(error)
        self.cost.append(float(np.sum(self.weights * error**2)))
        self.wall_time.append(time.perf_counter() - self.tic)
        log.info("identify it=%d E=%.6e Λ=%s", len(self.cost) - 1, self.cost[-1],
                 np.array2string(np.asarray(values), precision=6, max_line_width=1000))   # one line per iteration

    def result(self, jacobian, forward_solves) -> IdentificationResult:
        """The frozen record, with the estimate's equilibria and Jacobian."""
        return IdentificationResult(
            success=bool(self.success), message=self.message, estimate=self.parameters[-1],
            parameters=tuple(self.parameters), cost=tuple(self.cost),
            measurement_error=tuple(self.measurement_error), wall_time=tuple(self.wall_time),
            jacobian=jacobian, solutions=self.solutions, forward_solves=int(forward_solves),
            failed_solves=self.failed_solves, branch_restarts=self.branch_restarts,
            branch_drift=self.branch_drift, iterations=self.iterations)
