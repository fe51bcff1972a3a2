"""The observation operator ``Λ → M(Λ)``: forward solves in every posture, then measurements.

A solve starts from the warm starts its caller passes
(:class:`~breastcore.inverse.warm_start.WarmStarts`), or cold; the only state kept between calls
is the forward model's caches and, with ``processes > 1``, its worker processes. It provides the
two Jacobians of issue #3:

- ``implicit``: at equilibrium ``g(u; p) = 0`` so ``du/dp = −K⁻¹ ∂g/∂p``, one
  back-substitution per parameter with the factorised exact Hessian ``K``;
- ``fd``: the paper's forward differences ``(M(Λ + ε Λ_j e_j) − M(Λ)) / (ε Λ_j)``,
  one extra (warm-started) solve per parameter and posture.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from breastcore.fem.terms import BulkNeoHookean, SkinMembrane, modulus_gradient
from breastcore.forward.model import ForwardModel
from breastcore.forward.records import SolveError, raise_first_failure
from breastcore.forward.reduced import reduced_start
from breastcore.forward.workers import Workers
from breastcore.inverse.measurements import QUANTITIES, measure
from breastcore.inverse.options import IdentificationOptions
from breastcore.inverse.warm_start import WarmStarts
from breastcore.model.parameters import IDENTIFIED, Parameters

#: Largest step of the R, H differences of the implicit Jacobian, per Chassaignac smoothing length δ:
#: the sticking back nodes' gradient bends on the length δ (see implicit_jacobian).
GEOMETRY_STEP_PER_SMOOTHING = 1e-3

#: The energy term and Lamé attribute that each material parameter scales.
_MODULI = {"lambda_breast": (BulkNeoHookean, "lam"), "mu_breast": (BulkNeoHookean, "mu"),
           "lambda_skin": (SkinMembrane, "lam"), "mu_skin": (SkinMembrane, "mu")}


class MeasurementModel:
    """``Λ ↦ M(Λ)`` for fixed postures, measurement set and the non-identified constants.

    Parameters
    ----------
    model : ForwardModel
    base : Parameters
        Supplies ρ, g, c, δ, t_s and θ_D; its Λ is replaced at each evaluation.
    postures : sequence of Posture
    measurement_set : {"paper15", "exact"}
    warm_radius : float
        The radius of the :class:`~breastcore.inverse.warm_start.WarmStarts` that
        :meth:`warm_starts` makes (and :meth:`fd_jacobian` uses): warm-start a solve
        only from equilibria whose Λ is within this relative distance (max over the six
        parameters) of the new Λ. The standing posture has more than one local
        equilibrium near the fold (the sliding back can settle in two states, 0.03 %
        apart in energy): a warm start from far away can land on another branch than
        the cold path that defines ``M(Λ)``, while nearby warm starts follow the same branch.
    processes : int
        The postures are solved in this many forked worker processes (the same results bit
        for bit with one PARDISO thread, the default; by round-off otherwise), forked at the
        first such solve and kept until :meth:`close`
        (:class:`~breastcore.forward.workers.Workers`): each keeps its copy of this model, as
        it was then (change nothing in a model whose workers run), with its PARDISO analyses
        and caches, and the factors of the posture it solved last. Serial inside a process
        that multiprocessing started (e.g. a ``fork_map`` worker). Worth it from the thin mesh up.
    reduced_snapshots : int
        0: solves beyond ``warm_radius`` are cold. n > 0 (default: that of
        :class:`~breastcore.inverse.options.IdentificationOptions`, 8): they start from
        :func:`~breastcore.forward.reduced.reduced_start` over the last n remembered
        equilibria of the :class:`WarmStarts` passed in (cold while it has none).
    tangent_starts : bool
        The ``tangent_starts`` of the :class:`WarmStarts` that :meth:`warm_starts` makes
        (default: that of :class:`~breastcore.inverse.options.IdentificationOptions`, True):
        after a Jacobian, solves start from the first-order predictor ``x⁰ + ∂x/∂Λ (Λ − Λ⁰)``.
    """

    def __init__(self, model: ForwardModel, base: Parameters, postures, measurement_set="paper15",
                 warm_radius=IdentificationOptions.warm_radius, processes=1,
                 reduced_snapshots=IdentificationOptions.reduced_snapshots,
                 tangent_starts=IdentificationOptions.tangent_starts):
        self.model = model
        self.base = base
        self.postures = tuple(postures)
        self.measurement_set = measurement_set
        self.quantities = QUANTITIES
        self.warm_radius = warm_radius
        if int(processes) < 1:
            raise ValueError(f"processes must be ≥ 1, got {processes!r}")
        self.processes = int(processes)
        self.reduced_snapshots = int(reduced_snapshots)
        self.tangent_starts = bool(tangent_starts)
        self.solves = 0                                  # a counter of forward solves, for the record
        self._workers = Workers(self, self.processes, functools.partial(model.after_fork, keep_analyses=True))

    @classmethod
    def from_problem(cls, problem, mesh=None, *, model=None, processes=1) -> "MeasurementModel":
        """``Λ ↦ M(Λ)`` of a :class:`~breastcore.problem.ProblemSpec` on ``mesh`` (or an existing ``model``).

        Constants, solver options, postures, measurement set and warm-start radius all
        come from ``problem``; ``processes`` only changes how the postures are run.
        ``problem`` must have identification options, whose warm-start radius this uses
        (:class:`~breastcore.problem.ProblemSpecError` otherwise: no default radius).
        """
        if problem.measurement_set is None:
            raise ValueError("this problem has no measurement set: it defines no M(Λ)")
        warm_radius = problem.warm_radius()
        if model is None:
            model = problem.forward_model(mesh)
        elif model.options != problem.solver:
            raise ValueError("the forward model's solver options are not the problem's")
        return cls(model, problem.parameters, problem.postures, problem.measurement_set,
                   warm_radius=warm_radius, processes=processes,
                   reduced_snapshots=problem.identification.reduced_snapshots,
                   tangent_starts=problem.identification.tangent_starts)

    def params(self, values) -> Parameters:
        return self.base.with_identified(values)

    def warm_starts(self) -> WarmStarts:
        """An empty warm-start policy of this model's radius (the first solve is cold)."""
        return WarmStarts(self.warm_radius, self.reduced_snapshots, self.tangent_starts)

    def solve(self, values, warm: WarmStarts | None = None, jacobian=False):
        """Equilibria of all postures at ``Λ = values``, from ``warm``'s starts (cold without). Raises SolveError.

        ``warm`` is not changed: the caller decides which equilibria to remember.

        With ``jacobian`` and ``processes > 1``, each worker also computes its
        posture's rows of :meth:`implicit_jacobian` at ``values`` (35 ms a posture on
        ultra-thin, in parallel), which ``implicit_jacobian`` then reuses; serially
        they are left to be computed when asked for.
        """
        params = self.params(values)
        starts = warm.starts(values, self.postures) if warm is not None else {p.name: None for p in self.postures}
        if warm is not None and warm.tangents:
            starts = self._admissible_starts(params, starts, warm.starts(values, self.postures, predict=False))
        if warm is not None and warm.history:
            starts = self._reduced_starts(params, starts, warm.history)
        if self.processes > 1:
            at = np.array(values, dtype=float) if jacobian else None
            if not self._workers.started:               # the analyses once, here: the workers inherit them
                self.model.analyse_slots(params.fold_angle, self.postures)
            solved = raise_first_failure(self._workers.map("_solve_posture",
                                                           [(params, p, starts[p.name], at) for p in self.postures]))
            solutions = {p.name: s for p, s in zip(self.postures, solved)}
            self.solves += len(self.postures)
        else:
            solutions = {}
            for posture in self.postures:
                solutions[posture.name] = self.model.solve(params, posture, starts[posture.name])
                self.solves += 1
        return {name: dataclasses.replace(s, cold_start=starts[name] is None) for name, s in solutions.items()}

    def _solve_posture(self, params, posture, start, jacobian_at=None):
        """One posture's equilibrium, in a worker of :meth:`solve` (a SolveError is returned, not raised); with
        ``jacobian_at`` (Λ), also its rows of :meth:`implicit_jacobian` there, which that then reuses."""
        self.model.release_other_slots(posture.name)     # one posture's factors held at a time
        try:
            solution = self.model.solve(params, posture, start)
        except SolveError as err:
            return err
        if jacobian_at is None:
            return solution
        rows = self._posture_jacobian(params, jacobian_at, posture, solution.position)
        return dataclasses.replace(solution, jacobian_rows=(jacobian_at, *rows))

    def close(self):
        """Shut down the worker processes of :meth:`solve` (none with ``processes = 1``); a later
        solve forks new ones. Also done when this model is garbage-collected, or at exit; closing
        (or a ``with`` block) frees the workers' memory at once."""
        self._workers.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _admissible_starts(self, params, predicted, fallback):
        """``predicted``, each start whose energy is not finite (an inverted tet) replaced by ``fallback``'s."""
        out = dict(predicted)
        for posture in self.postures:
            x = out[posture.name]
            if x is not None and x is not fallback[posture.name]:
                problem = self.model.problem(params, posture)
                if not np.isfinite(problem.value(problem.free(x))):
                    out[posture.name] = fallback[posture.name]
        return out

    def _reduced_starts(self, params, starts, history):
        """``starts`` with each missing (cold) one replaced by the reduced-space start over ``history``."""
        out = dict(starts)
        # the snapshots' reference positions by the cap map alone: model.reference would build
        # (and cache, evicting the trial's) each snapshot's whole bulk and skin geometry
        references = [self.model.map.positions(values[0], values[1]) for values, _ in history]   # R, H
        for posture in self.postures:
            if out[posture.name] is None:
                displacements = [positions[posture.name] - reference
                                 for (_, positions), reference in zip(history, references)]
                out[posture.name] = reduced_start(self.model, params, posture, displacements)
        return out

    @staticmethod
    def solved_cold(solutions) -> bool:
        """Whether every posture of ``solutions`` was solved cold (no warm start).

        Such equilibria are those that define ``M(Λ)``: a cold solve is
        reproducible bit for bit, so solving them cold again would repeat them.
        """
        return all(bool(s.cold_start) for s in solutions.values())

    def measure(self, solutions) -> np.ndarray:
        """``(posture, quantity)`` array of measurements, SI units."""
        rows = []
        for posture in self.postures:
            values = measure(self.model.mesh, solutions[posture.name].position, self.measurement_set)
            rows.append([values[q] for q in self.quantities])
        return np.array(rows)

    def implicit_jacobian(self, values, solutions, rel_step=1e-6, tangents=None) -> np.ndarray:
        """``∂M/∂Λ_j``, shape ``(posture, quantity, 6)``, in SI units per parameter unit.

        ``tangents``: a dict that, if given, receives ``{posture name: ∂x/∂Λ}``, each
        ``(N, 3, 6)`` in m per parameter unit (the equilibrium's derivative, fixed dofs included).

        Notes
        -----
        ``∂g/∂p`` is exact for the four moduli, on which ``g`` depends linearly
        (:func:`~breastcore.fem.terms.modulus_gradient`; no new problem is built), and a
        central difference of the free-dof gradient at fixed free dofs for R and H,
        which move the reference nodes and the fold through the smooth map (second
        order), with step ``h = min(rel_step·|p|, GEOMETRY_STEP_PER_SMOOTHING·δ, (R − H)/2)``
        (the last keeps both sides inside ``0 < H < R``):
        the smoothed Chassaignac gradient ``c u/√(|u|² + δ²)`` of a back node that
        sticks (``|u| ≲ δ``) bends on the length δ, so the difference's truncation
        error is ``O((h/δ)²)`` there (docs/identification.md). ``∂M/∂x·dx/dp`` is a
        central directional difference of the measurement functions, which are
        smooth by construction.
        """
        params = self.params(values)
        out = np.zeros((len(self.postures), len(self.quantities), len(IDENTIFIED)))
        for i, posture in enumerate(self.postures):
            solution = solutions[posture.name]
            cached = solution.jacobian_rows
            if cached is not None and np.array_equal(cached[0], np.asarray(values, dtype=float)):
                out[i], tangent = cached[1], cached[2]              # computed by the worker that solved it
            else:
                out[i], tangent = self._posture_jacobian(params, values, posture, solution.position, rel_step)
            if tangents is not None:
                tangents[posture.name] = tangent
        return out

    def _posture_jacobian(self, params, values, posture, x, rel_step=1e-6):
        """One posture's ``(quantity, 6)`` block of :meth:`implicit_jacobian` at equilibrium ``x``, and
        ``∂x/∂Λ``, ``(N, 3, 6)``.

        The six right-hand sides ``∂g/∂p_j`` are solved together, one multi-column solve with
        the factorised ``K``.
        """
        problem, factor = self.model.tangent(params, posture, x)
        z = problem.free(x)
        free = problem.assembler.free.reshape(-1, 3)
        rhs, moved = [], []                                   # ∂g/∂p_j; the fixed dofs' move ∂x/∂p_j
        for j, name in enumerate(IDENTIFIED):
            if name in _MODULI:
                kind, attribute = _MODULI[name]
                term = next(t for t in problem.energy.terms if isinstance(t, kind))
                scale = getattr(term, "thickness", 1.0)          # skin moduli enter as λ_s t_s, μ_s t_s
                rhs.append(scale * problem.free(modulus_gradient(term, attribute, x)))
                moved.append(np.zeros_like(x))
                continue
            h = min(rel_step * abs(values[j]), GEOMETRY_STEP_PER_SMOOTHING * params.smoothing,
                    0.5 * (values[0] - values[1]))          # R − h and H + h keep 0 < H < R
            plus = self.model.problem(params.replace(**{name: values[j] + h}), posture)
            minus = self.model.problem(params.replace(**{name: values[j] - h}), posture)
            rhs.append((plus.gradient(z) - minus.gradient(z)) / (2 * h))
            moved.append((plus.full(z) - minus.full(z)) / (2 * h))   # moves the fixed dofs (fold) with R, H
        solved = factor.solve(np.column_stack(rhs))
        out = np.zeros((len(self.quantities), len(IDENTIFIED)))
        for j, dx in enumerate(moved):
            dx[free] = -solved[:, j]
            out[:, j] = self._directional(x, dx)
        return out, np.stack(moved, axis=-1)

    def _directional(self, x, dx):
        scale = 1e-7 / max(np.abs(dx).max(), 1e-300)                # a 0.1 µm move of the fastest node
        plus = measure(self.model.mesh, x + scale * dx, self.measurement_set)
        minus = measure(self.model.mesh, x - scale * dx, self.measurement_set)
        return np.array([(plus[q] - minus[q]) / (2 * scale) for q in self.quantities])

    def fd_jacobian(self, values, solutions, rel_step=1e-3, central=False) -> np.ndarray:
        """Forward (or central) differences of ``M`` in each ``Λ_j``, each solve warm-started from ``solutions``.

        A step never leaves ``0 < H < R``: where ``H(1 + ε)`` would reach ``R`` the ``H`` column is a
        backward difference, and a central step in R or H is at most half of ``R − H``.
        """
        base = self.measure(solutions)
        warm = WarmStarts.at(self.warm_radius, solutions, values)
        out = np.zeros(base.shape + (len(IDENTIFIED),))
        for j in range(len(IDENTIFIED)):
            h = rel_step * values[j]
            if j == 1 and values[1] + h >= values[0]:           # H + h would reach R: step backwards
                h = -h
            if central and j in (0, 1):                          # R − h and H + h within 0 < H < R
                h = np.sign(h) * min(abs(h), 0.5 * (values[0] - values[1]))
            plus = np.array(values, float)
            plus[j] += h
            m_plus = self.measure(self.solve(plus, warm))
            if central:
                minus = np.array(values, float)
                minus[j] -= h
                out[..., j] = (m_plus - self.measure(self.solve(minus, warm))) / (2 * h)
            else:
                out[..., j] = (m_plus - base) / h
        return out
