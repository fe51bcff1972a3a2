"""The settings of a forward solve: tolerances, continuation, Newton or the CG baseline."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from breastcore.linalg.factorization import REFINEMENT_RTOL


@dataclass(frozen=True)
class SolverOptions:
    """Settings of the equilibrium solve; every default is documented in the README.

    Attributes
    ----------
    method : {"newton", "cg"}
        Newton with the exact Hessian (default) or the paper's non-linear CG.
    rtol : float
        Converged when ‖free-dof gradient‖ ≤ ``rtol`` × ‖gravity load vector‖.
    stage_rtol : float
        The looser tolerance of the intermediate continuation steps.
    smoothing_start : float
        δ (m) at which the gravity ramp is done before δ is lowered to its target. The
        default, 1e-6 m, is the default target δ: the ramp is done at the target, with no
        δ phase (issue #21: 0.65× the time of Table-1 identifications on the two finest
        paper levels together with the two options below; docs/benchmarks.md). 1e-4 m
        was the default before.
    max_iterations : int
        Newton iterations per continuation step (CG: ``cg_max_iterations``).
    min_step : float
        Smallest continuation step (in load factor or in decades of δ).
    cg_max_iterations : int
        Iterations of the ``cg`` baseline per continuation step.
    max_extensions : int
        Newton only: a step that reaches ``max_iterations`` while its energy still
        fell by more than 0.1 % over those iterations is continued from where it
        stopped, up to this many more times, before the step is halved. (Far from
        equilibrium, e.g. μ = 15 Pa without skin on all fours, the minimiser needs
        ~200 iterations and halving the load step does not shorten the way.)
    reuse_factor : float
        Newton's chord steps (:func:`~breastcore.nonlinear.newton.newton`'s ``reuse``): the
        last factorised Hessian is reused while the gradient norm falls to at most this
        fraction per iteration. Default 0.5. 0: a fresh factorisation every iteration, the
        method before issue #21 (kept selectable for the benchmarks).
    sliding_dual : bool
        Newton steps with the primal-dual sliding blocks of
        :class:`~breastcore.fem.sliding_dual.SlidingDual` (Chan-Golub-Mulet) instead of the
        exact Hessian's. The energy and the tolerance are unchanged; back nodes that go from
        sticking to slipping take fewer steps. Default True (issue #21, with ``inertia_shift`` and
        ``mixed_precision_min_dofs``: 0.7× the time of ultra-thin Table-1 identifications,
        docs/benchmarks.md).
        False: the exact Hessian, the method before.
    sliding_release : bool
        With ``sliding_dual``: a Newton step treats the sticking back nodes that the body pulls
        past 1.05 × the sliding threshold as slipping (a semismooth step of the unsmoothed law,
        ``SlidingDual.release``), so that the slip zone does not widen by one ring of nodes per
        iteration. Default True (docs/benchmarks.md, "Released sliding steps"); False: the
        primal-dual steps alone, the method before. Newton only: no effect with ``method="cg"``
        or without ``sliding_dual``.
    inertia_shift : bool
        Newton's indefinite steps (:func:`~breastcore.nonlinear.newton.newton`'s
        ``inertia_shift``): a diagonal shift just large enough for a positive-definite
        step matrix, before the PSD projection. Default True; False: the projection
        directly, the method before.
    mixed_precision_min_dofs : int
        Newton and Jacobian factorisations of at least this many free dofs are done in
        single precision and refined in double to ‖b − Kx‖ ≤ 1e-10 ‖b‖
        (:class:`~breastcore.linalg.factorization.Factorization`): 1.3-1.6× faster per
        factorisation and solve on the paper's levels (611-8386 dofs, one thread). Default
        0: every level. 100000, the threshold before, keeps the paper's levels in double.
    step_rtol : float
        Newton's directions are solved to ``‖K d + b‖ ≤ step_rtol ‖b‖`` (the forcing term of an
        inexact Newton method; ``b`` the step's right-hand side, the gradient but at released
        sliding nodes): a single-precision factor is refined only as far as that, and on
        the paper's levels its first solve mostly meets 1e-3 already (median 1.5e-6, largest
        1.6e-3 in a cold ultra-thin solve). An exact or chord step that ends a solve is retaken
        along the direction refined to 1e-10, so that equilibria, and central differences of
        M(Λ), are as reproducible as with refined steps; Jacobian solves refine to 1e-10. Default
        1e-3; 1e-10 (the least allowed) refines every step, the method before.
    skip_futile_shifts : bool
        With ``inertia_shift``: an indefinite step goes to the PSD projection directly where the
        shifts cannot help: more than 7 negative pivots, or no fewer than at the last iteration
        of the same Newton solve whose shifts all failed
        (:data:`~breastcore.nonlinear.indefinite.MAX_SHIFT_PIVOTS`). Default True; False tries the
        shifts at every indefinite step, the method before.
    deep_indefinite_skips : int
        Newton's steps deep in an indefinite phase (:func:`~breastcore.nonlinear.newton.newton`'s
        ``deep_skips``): after an exact factorisation with more than 14 negative pivots
        (:data:`~breastcore.nonlinear.indefinite.DEEP_INDEFINITE_PIVOTS`), this many fresh steps take
        the PSD projection directly. The exact factorisation there would only report the inertia
        (with ``skip_futile_shifts`` the shifts are not tried at that depth), and the projected step
        is the one taken after it, so the path is the same while the count stays above 7. No effect
        without ``inertia_shift`` and ``skip_futile_shifts``, where the skipped factorisation could
        change the step. Default 3 (docs/benchmarks.md, "Deep indefinite phases"); 0: an exact
        factorisation at every fresh step, the method before.
    max_final_attempts : int
        The final δ step (full gravity, target δ, full tolerance) may fail this many
        times, each from a different converged neighbour, before the solve raises.
        Without a δ phase (target δ ≥ ``smoothing_start``) the final step is the
        gravity step, which is halved down to ``min_step`` as before: a shorter load
        step does bring the start closer.
        The last step's failures are at the tolerance, not on the way: in 652
        identification logs (the full paper scene's 545 runs and 107 others) no
        final step succeeded after failing twice, while 37 failed solves had
        retried it 15 times each, halving towards ``min_step``: 1,675 s in all,
        against 241 s up to a third failure (docs/identification.md).
    """

    method: str = "newton"
    rtol: float = 1e-8
    stage_rtol: float = 1e-5
    smoothing_start: float = 1e-6
    max_iterations: int = 100
    min_step: float = 1.0 / 256
    cg_max_iterations: int = 20000
    max_extensions: int = 4
    max_final_attempts: int = 3
    reuse_factor: float = 0.5
    sliding_dual: bool = True
    sliding_release: bool = True
    inertia_shift: bool = True
    mixed_precision_min_dofs: int = 0
    step_rtol: float = 1e-3
    skip_futile_shifts: bool = True
    deep_indefinite_skips: int = 3

    def __post_init__(self):
        if self.method not in ("newton", "cg"):
            raise ValueError(f"solver method must be 'newton' or 'cg', got {self.method!r}")
        for name in ("rtol", "stage_rtol", "smoothing_start", "min_step"):
            if not getattr(self, name) > 0:
                raise ValueError(f"solver option {name} must be > 0")
        if not 0.0 <= self.reuse_factor < 1.0:
            raise ValueError("solver option reuse_factor must be in [0, 1)")
        if isinstance(self.step_rtol, bool) or not REFINEMENT_RTOL <= self.step_rtol < 1:
            raise ValueError(f"solver option step_rtol must be in [{REFINEMENT_RTOL:g}, 1) (below it the "
                             f"refinement cannot get), got {self.step_rtol!r}")
        object.__setattr__(self, "step_rtol", float(self.step_rtol))
        for name in ("sliding_dual", "sliding_release", "inertia_shift", "skip_futile_shifts"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"solver option {name} must be true or false, got {getattr(self, name)!r}")
            object.__setattr__(self, name, bool(getattr(self, name)))       # JSON-able in the spec
        for name in ("mixed_precision_min_dofs", "deep_indefinite_skips"):
            value = getattr(self, name)
            if isinstance(value, bool) or not (isinstance(value, (int, np.integer)) and value >= 0):
                raise ValueError(f"solver option {name} must be an integer ≥ 0, got {value!r}")
            object.__setattr__(self, name, int(value))
        if int(self.max_final_attempts) < 1:
            raise ValueError("solver option max_final_attempts must be ≥ 1")
