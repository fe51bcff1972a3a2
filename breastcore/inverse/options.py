"""The settings of an identification (:func:`breastcore.inverse.identify.identify`), apart from its algorithm.

A module of its own so that a :class:`~breastcore.problem.ProblemSpec`, which every
stage writes, does not import the identification code: an edit of ``identify.py``
reruns the identifications, not the solves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class IdentificationOptions:
    """Settings of :func:`identify`; defaults documented in ``docs/identification.md``.

    Attributes
    ----------
    method : {"lm", "gauss-newton"}
        Levenberg–Marquardt in log/logit variables, or the paper's Gauss–Newton.
    jacobian : {"implicit", "fd"}
        The Jacobian of M(Λ) from the converged equilibria, or the paper's forward differences.
    fd_step : float
        Relative step ε of the finite-difference Jacobian.
    cost_tol : float
        Gauss–Newton stops when the cost decrease is below ``cost_tol`` (ε_m).
    cost_rtol : float
        Both methods: stop, converged, after the first accepted step that lowers
        the cost by less than ``cost_rtol`` times the cost before it,
        ``E(Λⁿ) − E(Λⁿ⁺¹) < cost_rtol · E(Λⁿ)``: the paper's ε_m test made
        relative. 0 (default) turns it off. Unlike ``ftol``, it asks nothing of
        the step's agreement with the quadratic model, so a run stops exactly
        where its recorded cost history first meets it: a run with
        ``cost_rtol`` is the prefix of the same run without it.
    xtol, ftol, gtol : float
        ``least_squares`` stopping tolerances (LM).
    max_iterations : int
        Accepted steps (iterations) of the whole identification, branch restarts
        included: the paper reports its results "after 25 iterations". LM also
        stops after ``MAX_EVALUATIONS_PER_ITERATION × max_iterations`` residual
        evaluations (trial points, rejected ones included).
    noise : float
        Relative 1σ measurement noise of the uncertainty model (0.10 = 10 %).
    fixed_iterations : bool
        Gauss–Newton only: run exactly ``max_iterations`` iterations without the
        ε_m test, as the paper's parameter-evolution runs do ("after 25
        iterations"). The result is then never labelled converged.
    initial_trust_radius : float
        LM only: the first trust-region radius, in the log/logit variables (0.5:
        moduli scaled by at most e^0.5 ≈ 1.65 in the first trial step). scipy's
        ``trf`` would otherwise start at ‖z₀‖ ≈ 15, a unit-dependent radius whose
        first trial steps scale moduli by up to e^±10; from ±60 % starts on the
        coarse mesh this recovered Λ̄ in 11 of 20 starts, against 20 of 20 with 0.5
        (docs/identification.md, "Inverse crime").
    warm_radius : float
        Warm-start a forward solve only from equilibria whose Λ is within this
        relative distance (max over the six parameters) of the new Λ; farther away,
        solve cold (:class:`~breastcore.inverse.operator.MeasurementModel`), unless a
        reduced or tangent start below applies. 0 turns warm starts between different Λ
        off (tangent starts too), and with them the branch check.
    reduced_snapshots : int
        n > 0: start a solve beyond ``warm_radius`` from the energy's minimiser over the span of
        the displacements of the last n remembered equilibria, not cold; 0: cold (with
        ``tangent_starts`` False, the method before issue #21). Default 8. With ``tangent_starts``
        it serves only solves with no tangent at hand. (:func:`~breastcore.forward.reduced.reduced_start`; the
        branch check then compares the estimate with a cold solve.) Like any start, it can
        change which equilibrium a far trial point reaches; the branch check guards the
        estimate.
    tangent_starts : bool
        With ``warm_radius > 0`` and the implicit Jacobian: after each Jacobian, start every
        solve, near or far, from the first-order predictor ``x⁰ + ∂x/∂Λ (Λ − Λ⁰)`` of the
        equilibria x⁰ at the Jacobian's Λ⁰ (a predictor that inverts a tet is dropped for the
        starts above). ``∂x/∂Λ`` is the Jacobian's own intermediate result. Default True;
        False: the starts of ``warm_radius`` and ``reduced_snapshots`` only, the method before
        it (:class:`~breastcore.inverse.warm_start.WarmStarts`).
    """

    method: str = "lm"
    jacobian: str = "implicit"
    fd_step: float = 1e-4
    cost_tol: float = 1e-14
    cost_rtol: float = 0.0
    xtol: float = 1e-8
    ftol: float = 1e-8
    gtol: float = 1e-10
    max_iterations: int = 50
    noise: float = 0.10
    initial_trust_radius: float = 0.5
    fixed_iterations: bool = False
    warm_radius: float = 0.05
    reduced_snapshots: int = 8
    tangent_starts: bool = True

    def __post_init__(self):
        if self.method not in ("lm", "gauss-newton"):
            raise ValueError(f"method must be 'lm' or 'gauss-newton', got {self.method!r}")
        if self.jacobian not in ("implicit", "fd"):
            raise ValueError(f"jacobian must be 'implicit' or 'fd', got {self.jacobian!r}")
        if not (self.fd_step > 0 and self.noise > 0 and self.max_iterations > 0 and self.initial_trust_radius > 0):
            raise ValueError("fd_step, noise, max_iterations and initial_trust_radius must be > 0")
        if not 0 <= self.cost_rtol < 1:
            raise ValueError(f"cost_rtol must be in [0, 1), got {self.cost_rtol!r}")
        if not 0 <= self.warm_radius < np.inf:
            raise ValueError(f"warm_radius must be finite and ≥ 0, got {self.warm_radius!r}")
        if int(self.reduced_snapshots) != self.reduced_snapshots or self.reduced_snapshots < 0:
            raise ValueError(f"reduced_snapshots must be an integer ≥ 0, got {self.reduced_snapshots!r}")
        if not isinstance(self.tangent_starts, (bool, np.bool_)):
            raise ValueError(f"tangent_starts must be True or False, got {self.tangent_starts!r}")
        if self.fixed_iterations and self.method != "gauss-newton":
            raise ValueError("fixed_iterations applies to method 'gauss-newton' only")
