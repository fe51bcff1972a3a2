"""The forward model: equilibrium shape of the breast in one posture.

A :class:`ForwardModel` holds one fixed-topology mesh; ``(R, H)`` move its nodes
through the smooth :class:`~breastcore.geometry.CapMap`. :func:`solve_posture`
reaches equilibrium by adaptive continuation, first in the gravity load factor
and then in the Chassaignac smoothing δ down to its target, with a Newton solve
(or the paper's conjugate-gradient baseline) at each step.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field

import numpy as np

from .assembly import FreeDofAssembler
from .energy import BulkNeoHookean, Chassaignac, Composite, Gravity, SkinMembrane
from .geometry import CapMap
from .parallel import fork_map
from .mesh import CapMesh, refold
from .parameters import Parameters
from .postures import Posture
from .saddle import escape_saddle
from .solver import Factorization, hessian_inertia, newton

log = logging.getLogger(__name__)


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
        δ (m) at which the gravity ramp is done before δ is lowered to its target.
    max_iterations : int
        Newton iterations per continuation step (CG: ``cg_max_iterations``).
    min_step : float
        Smallest continuation step (in load factor or in decades of δ).
    cg_max_iterations : int
    max_extensions : int
        Newton only: a step that reaches ``max_iterations`` while its energy still
        fell by more than 0.1 % over those iterations is continued from where it
        stopped, up to this many more times, before the step is halved. (Far from
        equilibrium, e.g. μ = 15 Pa without skin on all fours, the minimiser needs
        ~200 iterations and halving the load step does not shorten the way.)
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
    smoothing_start: float = 1e-4
    max_iterations: int = 100
    min_step: float = 1.0 / 256
    cg_max_iterations: int = 20000
    max_extensions: int = 4
    max_final_attempts: int = 3

    def __post_init__(self):
        if self.method not in ("newton", "cg"):
            raise ValueError(f"solver method must be 'newton' or 'cg', got {self.method!r}")
        for name in ("rtol", "stage_rtol", "smoothing_start", "min_step"):
            if not getattr(self, name) > 0:
                raise ValueError(f"solver option {name} must be > 0")
        if int(self.max_final_attempts) < 1:
            raise ValueError("solver option max_final_attempts must be ≥ 1")


class SolveError(RuntimeError):
    """A solve that did not reach its tolerance; carries the diagnostics.

    Attributes
    ----------
    iterations : int
        Newton (or CG) iterations spent in all continuation steps.
    gradient_norm, tolerance : float
        Free-dof gradient norm reached and the one asked for, N.
    min_det_F : float
        Smallest ``det F`` over the tets at the last admissible iterate.
    load_factor, smoothing : float
        Continuation level reached: fraction of gravity and δ (m).
    posture : str
    """

    def __init__(self, message, *, iterations, gradient_norm, tolerance, min_det_F,
                 load_factor, smoothing, posture):
        self.iterations = iterations
        self.gradient_norm = gradient_norm
        self.tolerance = tolerance
        self.min_det_F = min_det_F
        self.load_factor = load_factor
        self.smoothing = smoothing
        self.posture = posture
        self._message = message
        super().__init__(
            f"{posture}: {message} after {iterations} iterations; |g|={gradient_norm:.3e} N "
            f"(tolerance {tolerance:.3e} N), min det F={min_det_F:.3e}, "
            f"continuation reached load factor {load_factor:.4g}, δ={smoothing:.3e} m")

    def __reduce__(self):                                            # picklable (parallel postures)
        return (_rebuild_solve_error, (self._message, dict(
            iterations=self.iterations, gradient_norm=self.gradient_norm, tolerance=self.tolerance,
            min_det_F=self.min_det_F, load_factor=self.load_factor, smoothing=self.smoothing,
            posture=self.posture)))


def _rebuild_solve_error(message, fields):
    return SolveError(message, **fields)


@dataclass(frozen=True)
class PostureSolution:
    """Equilibrium of one posture. Positions in m, forces in N, energy in J."""

    posture: Posture
    position: np.ndarray
    converged: bool
    iterations: int
    continuation_steps: int
    gradient_norm: float
    tolerance: float
    energy: float
    min_det_F: float
    max_stretch: float
    wall_time: float
    extra: dict = field(default_factory=dict)

    @property
    def negative_eigenvalues(self) -> int:
        """Negative eigenvalues of the exact Hessian at the returned position (``-1``: unknown, no PARDISO).

        Computed at the solution itself, for Newton and CG solves, cold or warm. Zero
        at a stable equilibrium (a local minimum of ``J_h``); a saddle is left by
        :func:`~breastcore.saddle.escape_saddle` before returning, and > 0 only where
        that escape keeps it (a neutral direction, or a failed last round).
        """
        return int(self.extra.get("negative_pivots", -1))


class EquilibriumProblem:
    """``J_h`` on the free dofs for one parameter set, gravity vector and δ."""

    def __init__(self, model: "ForwardModel", params: Parameters, acceleration, smoothing):
        self.model = model
        ref = model.reference(params.R, params.H)
        mesh = model.mesh
        self.reference = ref
        self.assembler = model.assembler(params.fold_angle)
        self.bulk = BulkNeoHookean(ref, mesh.tets, params.lambda_breast, params.mu_breast)
        self.gravity = Gravity(ref, mesh.tets, params.density, acceleration)
        self.energy = Composite([
            self.bulk,
            SkinMembrane(ref, mesh.skin_triangles, params.lambda_skin, params.mu_skin, params.skin_thickness),
            self.gravity,
            Chassaignac(ref, mesh.back_triangles, params.chassaignac, smoothing),
        ])
        load = float(np.linalg.norm(self.gravity.load))
        self.energy_scale = max(load, 1e-30) * params.R
        self.length_scale = params.R

    def full(self, z):
        """Node positions ``(N, 3)`` from the free dofs (fixed dofs at their reference values)."""
        return self.assembler.expand(z, self.reference)

    def free(self, x):
        return self.assembler.restrict(x)

    def value(self, z):
        return self.energy.value(self.full(z))

    def gradient(self, z):
        return self.free(self.energy.gradient(self.full(z)))

    def hessian(self, z, project=False):
        return self.assembler.assemble_terms(self.energy.nonlinear_terms, self.full(z), project)

    @property
    def pattern(self):
        """Sparsity pattern of :meth:`hessian` (its PARDISO symbolic analysis is reused)."""
        return self.assembler.pattern


class ForwardModel:
    """Fixed-topology forward model on one reference mesh.

    Parameters
    ----------
    mesh : CapMesh
        The mesh whose topology is kept; ``(R, H)`` move its nodes smoothly.
    options : SolverOptions
    """

    def __init__(self, mesh: CapMesh, options: SolverOptions = SolverOptions()):
        self.mesh = mesh
        self.options = options
        self.map = CapMap(mesh)
        self._assemblers = {}

    def reference(self, R, H):
        """Gravity-free node positions for ``(R, H)``, ``(N, 3)`` m."""
        return self.map.positions(R, H)

    def free_mask(self, fold_angle):
        """``(N, 3)`` bool: fold nodes fixed, back nodes fixed in ``y`` (spec §2)."""
        fold = self.mesh.fold if np.isclose(fold_angle, self.mesh.fold_angle) else refold(self.mesh, fold_angle).fold
        free = np.ones((len(self.mesh.nodes), 3), dtype=bool)
        free[self.mesh.back, 1] = False
        free[fold] = False
        return free

    def assembler(self, fold_angle):
        key = round(float(fold_angle), 9)
        if key not in self._assemblers:
            conns = [self.mesh.tets, self.mesh.skin_triangles, np.unique(self.mesh.back_triangles)[:, None]]
            self._assemblers[key] = FreeDofAssembler(conns, self.free_mask(fold_angle))
        return self._assemblers[key]

    def problem(self, params, posture, load_factor=1.0, smoothing=None):
        accel = load_factor * posture.gravity(params.gravity_magnitude)
        return EquilibriumProblem(self, params, accel, params.smoothing if smoothing is None else smoothing)

    def tolerance(self, params, posture):
        """Absolute stopping tolerance: ``rtol`` × ‖gravity load vector‖ (N).

        Without gravity (g = 0) the load is zero; the force scale ``μ R²`` replaces it.
        """
        load = float(np.linalg.norm(self.problem(params, posture).gravity.load))
        return self.options.rtol * (load if load > 0 else params.mu_breast * params.R**2)

    def tangent(self, params, posture, position):
        """Exact free-dof Hessian at ``position``, factorised (for sensitivities)."""
        problem = self.problem(params, posture)
        return problem, Factorization(problem.hessian(problem.free(position)), problem.pattern)

    def solve(self, params: Parameters, posture: Posture, start=None) -> PostureSolution:
        """Equilibrium of ``posture``; see :func:`solve_posture`."""
        return solve_posture(self, params, posture, start)

    def after_fork(self):
        """In a forked child: drop the parent's PARDISO analyses, so that this process makes its own."""
        for assembler in self._assemblers.values():
            assembler._pattern = None

    def solve_postures(self, params: Parameters, postures, starts=None, processes=1,
                       finish=None) -> list[PostureSolution]:
        """Equilibria of several postures, optionally in ``processes`` forked worker processes.

        The postures are independent solves, so running them in parallel gives the
        same results bit for bit (PARDISO runs single-threaded, see
        :data:`breastcore.solver.PARDISO_THREADS_ENV`). ``starts`` maps a posture
        name to a warm start. Falls back to one process where ``fork`` is not
        available or this process may not have children (a daemon). ``finish(posture,
        solution)``, if given, runs in the worker after each successful solve and
        returns a dict merged into ``solution.extra`` (work on the solution that
        then runs in parallel too, e.g. its Jacobian).

        Raises
        ------
        SolveError
            The first posture that failed (after all have run).
        """
        postures = list(postures)
        starts = starts or {}

        def solve(index):                                  # a SolveError is returned, so that all run
            try:
                solution = self.solve(params, postures[index], starts.get(postures[index].name))
            except SolveError as err:
                return err
            if finish is not None:
                solution.extra.update(finish(postures[index], solution))
            return solution

        outcomes = fork_map(solve, len(postures), processes or 1, after_fork=self.after_fork)
        for outcome in outcomes:
            if isinstance(outcome, SolveError):
                raise outcome
        return outcomes


def _cg_minimiser(model):
    """The CG baseline with :func:`~breastcore.solver.newton`'s call signature (``avoid_saddles`` has no
    effect: CG follows the gradient and is not drawn to saddles as Newton's step is)."""
    from .cg import conjugate_gradient

    def minimise(problem, z, tolerance, max_iterations=None, avoid_saddles=False):
        return conjugate_gradient(problem, z, tolerance, model.options.cg_max_iterations)
    return minimise


def _minimise(model, problem, z, tolerance):
    if model.options.method == "cg":
        return _cg_minimiser(model)(problem, z, tolerance)
    result = newton(problem, z, tolerance, model.options.max_iterations)
    if result.success and result.negative_pivots:                  # an unstable equilibrium: leave it
        return escape_saddle(problem, result, model.options.max_iterations)
    iterations = result.iterations
    for _ in range(model.options.max_extensions):                  # still going downhill: keep going
        if result.success or result.message != "iteration limit":
            break
        start_energy = problem.value(z)
        if not start_energy - result.energy > 1e-3 * abs(result.energy):
            break
        z = result.x
        log.debug("iteration limit with the energy still falling (%.6e → %.6e): continuing", start_energy,
                  result.energy)
        result = newton(problem, z, tolerance, model.options.max_iterations)
        iterations += result.iterations
    return dataclasses.replace(result, iterations=iterations) if iterations != result.iterations else result


def _diagnostics(problem, x):
    F = problem.bulk.deformation_gradient(x)
    det = np.linalg.det(F)
    stretch = np.sqrt(np.linalg.eigvalsh(np.einsum("nki,nkj->nij", F, F)).max())
    return float(det.min()), float(stretch)


def solve_posture(model: ForwardModel, params: Parameters, posture: Posture, start=None) -> PostureSolution:
    r"""Minimise ``J_h`` for one posture by adaptive continuation.

    The path parameter ``t`` runs over ``[0, 1]`` for the gravity load factor
    (at δ = max(δ, ``smoothing_start``)) and then over ``[1, 2]`` for δ, lowered
    log-linearly to its target, at most one decade per step. Each step is a Newton
    solve warm-started from the last converged state; a failed step is halved, a
    good one lengthened ×2.
    With ``start`` (a previous solution, ``(N, 3)``), the target problem is tried
    directly first, and continuation in δ from ``start`` is the fallback.

    Raises
    ------
    SolveError
        When a continuation step falls below ``options.min_step``, or the final
        δ step has failed ``options.max_final_attempts`` times.
    """
    opts = model.options
    tic = time.perf_counter()
    tolerance = model.tolerance(params, posture)
    loose = tolerance * opts.stage_rtol / opts.rtol
    delta_target = params.smoothing
    delta_start = max(delta_target, opts.smoothing_start)
    decades = np.log10(delta_start / delta_target)

    def level(t):
        if t <= 1.0:
            return t, delta_start
        return 1.0, delta_start * 10.0 ** (-decades * (t - 1.0))

    iterations = 0
    steps = 0
    reference = model.reference(params.R, params.H)
    if start is not None:
        problem = model.problem(params, posture)
        start = np.asarray(start, dtype=float)
        scaled = _rescale_start(problem, start, reference)
        if np.isfinite(problem.value(problem.free(scaled))) or not np.isfinite(problem.value(problem.free(start))):
            start = scaled
        z = problem.free(start)
        if np.isfinite(problem.value(z)):
            result = _minimise(model, problem, z, tolerance)
            iterations += result.iterations
            steps += 1
            if result.success:
                return _finish(model, problem, result, posture, iterations, steps, tic)
        t, x = 1.0, start
        if not np.isfinite(model.problem(params, posture, 1.0, delta_start).value(z)):
            t, x = 0.0, reference
    else:
        t, x = 0.0, reference
    t_end = 2.0 if decades > 0 else 1.0
    max_delta_step = 1.0 / max(decades, 1.0)          # δ falls at most one decade per step
    dt = 1.0 if t < 1.0 else max_delta_step
    final_failures = 0
    x_delta = None                                    # δ at which x is an equilibrium (None: unknown)
    while True:
        t_next = min(t + dt, 1.0 if t < 1.0 else t_end)
        load, delta = level(t_next)
        problem = model.problem(params, posture, load, delta)
        final = t_next >= t_end
        z = problem.free(x)
        if t >= 1.0 and x_delta is not None and delta < x_delta:
            z = _smoothing_predictor(model, problem, x, reference, x_delta, delta, z)
        result = _minimise(model, problem, z, tolerance if final else loose)
        iterations += result.iterations
        steps += 1
        log.debug("%s: step t=%.4f load=%.4g δ=%.3e: %s in %d iterations", posture.name, t_next, load, delta,
                  result.message, result.iterations)
        if result.success:
            if final:
                return _finish(model, problem, result, posture, iterations, steps, tic)
            t, x, x_delta = t_next, problem.full(result.x), delta
            dt = min(2.0 * dt, 1.0 if t < 1.0 else max_delta_step)
            continue
        final_failures += final and t >= 1.0           # a failed last δ step; a load step is halved on
        log.info("%s: continuation step t=%.4f→%.4f failed (%s); halving", posture.name, t, t_next, result.message)
        dt *= 0.5
        if dt < opts.min_step or final_failures >= opts.max_final_attempts:
            min_det = _diagnostics(problem, problem.full(result.x))[0]
            load, delta = level(t)
            why = "continuation stalled" if dt < opts.min_step else \
                f"final step failed {final_failures} times"
            raise SolveError(f"{why}: {result.message}", iterations=iterations,
                             gradient_norm=result.gradient_norm, tolerance=tolerance, min_det_F=min_det,
                             load_factor=load, smoothing=delta, posture=posture.name)


def _rescale_start(problem, start, reference):
    """A warm start whose fixed fold nodes are moved onto their new positions.

    A start computed for other ``(R, H)`` has its fold nodes on the old base rim;
    the problem fixes them on the new one, and the tets at the fold, which the
    standing posture compresses to ``det F`` ~ 1e-5, invert under that jump. The
    start is scaled in ``x`` and ``z`` (the torso plane) by the least-squares
    factor that carries its fold nodes to their new positions: a linear map with
    positive determinant, so every tet keeps its orientation. The smooth cap map
    scales the reference in ``x`` and ``z`` by the same factor (the base radius
    ratio), so this also transfers most of the change of reference; on
    ultra-thin, after a 1 % change of all six parameters, it cuts the warm
    Newton iterations from 11-44 to 3-5. A start for the same ``(R, H)`` is
    returned unchanged (factor 1).
    """
    fixed = ~problem.assembler.free.reshape(-1, 3)[:, 0]            # fold nodes (fixed in x)
    old, new = start[fixed][:, [0, 2]], reference[fixed][:, [0, 2]]
    norm = float(np.sum(old * old))
    if not fixed.any() or norm == 0.0:
        return start
    scaled = start.copy()
    scaled[:, [0, 2]] *= float(np.sum(old * new)) / norm
    return scaled


#: Back nodes that slip less than this many δ count as sticking in :func:`_smoothing_predictor`.
STICK_SLIPS = 3.0


def _smoothing_predictor(model, problem, x, reference, delta_old, delta_new, z):
    """Starting free dofs for a δ step: the slip of sticking back nodes scaled by ``δ_new/δ_old``.

    With the tangential force on a back node held fixed, the equilibrium slip of
    ``w u / sqrt(|u|² + δ²) = f`` is proportional to δ, so a node in the stick zone
    (``|u| <`` :data:`STICK_SLIPS` δ_old) is moved to ``u δ_new/δ_old``; slipping
    nodes keep their slip. Newton from the unscaled slip overshoots (the smoothed
    norm is nearly flat radially for ``|u| ≫ δ``) and needs many damped steps.
    Returns ``z`` unchanged if the predicted state is inadmissible.
    """
    back = np.flatnonzero(model.mesh.back)
    u = x[back] - reference[back]
    stick = back[np.linalg.norm(u, axis=1) < STICK_SLIPS * delta_old]
    if stick.size == 0:
        return z
    predicted = np.array(x, dtype=float, copy=True)
    predicted[stick] = reference[stick] + (x[stick] - reference[stick]) * (delta_new / delta_old)
    z_pred = problem.free(predicted)
    return z_pred if np.isfinite(problem.value(z_pred)) else z


def _settle(model, problem, result):
    """``result`` with the inertia of the exact Hessian at its own point, a saddle left first.

    Newton's inertia comes from the Hessian it factorised before its last step, and a
    CG solve or a warm solve that needs no iteration factorises none: the inertia of
    the returned equilibrium is computed here (one factorisation, unless the saddle
    escape already did it). A saddle found so is left by the solve's own method
    (:func:`~breastcore.saddle.escape_saddle`), for Newton and CG alike.
    """
    if not result.inertia_at_x:
        result = dataclasses.replace(result, negative_pivots=hessian_inertia(problem, result.x), inertia_at_x=True)
    if not result.negative_pivots:
        return result
    minimise = _cg_minimiser(model) if model.options.method == "cg" else newton
    escaped = escape_saddle(problem, result, model.options.max_iterations, minimise=minimise)
    if not escaped.inertia_at_x:
        escaped = dataclasses.replace(escaped, negative_pivots=hessian_inertia(problem, escaped.x), inertia_at_x=True)
    return escaped


def _finish(model, problem, result, posture, iterations, steps, tic):
    extra_iterations = result.iterations
    result = _settle(model, problem, result)
    iterations += result.iterations - extra_iterations
    x = problem.full(result.x)
    min_det, stretch = _diagnostics(problem, x)
    log.info("%s: converged in %d iterations (%d continuation steps), |g|=%.3e N", posture.name,
             iterations, steps, result.gradient_norm)
    extra = {}
    if result.negative_pivots is not None:
        extra["negative_pivots"] = int(result.negative_pivots)         # at x; > 0: a saddle kept (see _settle)
    return PostureSolution(posture, x, True, iterations, steps, result.gradient_norm, result.tolerance,
                           result.energy, min_det, stretch, time.perf_counter() - tic, extra)
