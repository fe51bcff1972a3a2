"""The forward model: one mesh, the equilibrium of any posture, several postures in parallel.

A :class:`ForwardModel` holds one fixed-topology mesh; ``(R, H)`` move its nodes
through the smooth :class:`~breastcore.model.geometry.CapMap`; each posture is solved by
:func:`breastcore.forward.continuation.solve_posture`.
"""

from __future__ import annotations

import collections
import functools

import numpy as np

from breastcore.fem.assembly import FreeDofAssembler
from breastcore.fem.bulk import BulkNeoHookean
from breastcore.fem.loads import Chassaignac, Gravity
from breastcore.fem.skin import SkinMembrane
from breastcore.forward.continuation import solve_posture
from breastcore.forward.equilibrium import EquilibriumProblem
from breastcore.forward.options import SolverOptions
from breastcore.forward.parallel import fork_map
from breastcore.forward.records import PostureSolution, SolveError, raise_first_failure
from breastcore.linalg.factorization import Factorization, analyse
from breastcore.model.geometry import CapMap
from breastcore.model.mesh import CapMesh, refold
from breastcore.model.parameters import Parameters
from breastcore.model.postures import Posture

#: ``(R, H)`` reference geometries a :class:`ForwardModel` keeps, newest first: an implicit Jacobian visits
#: five (Λ, and R ± h, H ± h, for every posture); older trial points are rarely revisited.
GEOMETRY_CACHE_ENTRIES = 8
#: ... and at most this many bytes of their bulk and skin arrays (the gravity and sliding terms are small), the newest
#: always kept: 0.65 MB each on medium, 3 MB on ultra-thin, about 75 MB on fine50k.
GEOMETRY_CACHE_BYTES = 512 * 2**20


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
        self._patterns = {}                   # (fold angle, posture name) → that posture's pattern
        self._tangents = {}                   # posture → (params, load, δ, x, factor) of its last equilibrium
        self._geometries = collections.OrderedDict()

    def reference(self, R, H):
        """Gravity-free node positions for ``(R, H)``, ``(N, 3)`` m (read-only: cached)."""
        return self._geometry(R, H)["reference"]

    def _geometry(self, R, H):
        """The reference positions and the terms' reference arrays at ``(R, H)``, built once.

        A continuation builds a problem per step and posture at the same ``(R, H)``, and
        the identification's trial points and Jacobian revisit a few: the most recent
        are kept, up to :data:`GEOMETRY_CACHE_ENTRIES` and :data:`GEOMETRY_CACHE_BYTES`.
        The terms are templates; a problem takes copies with its moduli, load and δ
        (``with_moduli``…), so its arrays are those a fresh build would compute, bit for bit.
        """
        key = (float(R), float(H))
        if key in self._geometries:
            self._geometries.move_to_end(key)
            return self._geometries[key]
        reference = self.map.positions(R, H)
        reference.flags.writeable = False
        mesh = self.mesh
        geometry = dict(reference=reference,
                        bulk=BulkNeoHookean(reference, mesh.tets, 0.0, 0.0),
                        skin=SkinMembrane(reference, mesh.skin_triangles, 0.0, 0.0, 1.0),
                        gravity={}, chassaignac={})
        geometry["bytes"] = reference.nbytes + sum(                  # the connectivity is the mesh's, not copied
            a.nbytes for term in (geometry["bulk"], geometry["skin"]) for name, a in vars(term).items()
            if isinstance(a, np.ndarray) and name != "connectivity")
        self._geometries[key] = geometry
        while len(self._geometries) > 1 and (len(self._geometries) > GEOMETRY_CACHE_ENTRIES or sum(
                g["bytes"] for g in self._geometries.values()) > GEOMETRY_CACHE_BYTES):
            self._geometries.popitem(last=False)
        return geometry

    def energy_terms(self, params: Parameters, acceleration, smoothing):
        """The four terms of ``J_h`` at ``params`` under ``acceleration`` (m s⁻²) and δ = ``smoothing`` (m).

        Returns ``(bulk, skin, gravity, chassaignac)``, built from the cached reference
        geometry of ``(R, H)`` (:meth:`_geometry`).
        """
        geometry = self._geometry(params.R, params.H)
        sliding = geometry["chassaignac"].get(params.chassaignac)
        if sliding is None:
            sliding = geometry["chassaignac"][params.chassaignac] = Chassaignac(
                geometry["reference"], self.mesh.back_triangles, params.chassaignac, smoothing)
        return (geometry["bulk"].with_moduli(params.lambda_breast, params.mu_breast),
                geometry["skin"].with_moduli(params.lambda_skin, params.mu_skin, params.skin_thickness),
                self._gravity(params, acceleration), sliding.with_smoothing(smoothing))

    def _gravity(self, params, acceleration) -> Gravity:
        """The gravity term at ``params`` under ``acceleration``, from the cached nodal masses of ``(R, H, ρ)``."""
        geometry = self._geometry(params.R, params.H)
        gravity = geometry["gravity"].get(params.density)
        if gravity is None:
            gravity = geometry["gravity"][params.density] = Gravity(geometry["reference"], self.mesh.tets,
                                                                    params.density, np.zeros(3))
        return gravity.with_acceleration(acceleration)

    def mesh_at(self, params) -> CapMesh:
        """The gravity-free mesh at ``params``' R and H, with its fold at ``params.fold_angle``."""
        return refold(self.map.mesh_at(params.R, params.H), params.fold_angle)

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
            self._assemblers[key] = FreeDofAssembler(conns, self.free_mask(fold_angle),
                                                     self.options.mixed_precision_min_dofs)
        return self._assemblers[key]

    def pattern(self, fold_angle, slot):
        """The Hessian pattern of :meth:`assembler` with PARDISO handles of its own for ``slot``
        (a posture's name), so that each posture's last factor survives the others' solves."""
        key = (round(float(fold_angle), 9), slot)
        if key not in self._patterns:
            self._patterns[key] = self.assembler(fold_angle).pattern.sibling()
        return self._patterns[key]

    def problem(self, params, posture, load_factor=1.0, smoothing=None):
        accel = load_factor * posture.gravity(params.gravity_magnitude)
        return EquilibriumProblem(self, params, accel, params.smoothing if smoothing is None else smoothing,
                                  sliding_dual=self.options.sliding_dual, slot=posture.name,
                                  sliding_release=self.options.sliding_release)

    def tolerance(self, params, posture):
        """Absolute stopping tolerance: ``rtol`` × ‖gravity load vector‖ (N).

        Without gravity (g = 0) the load is zero; the force scale ``μ R²`` replaces it.
        """
        # only the gravity term: the same load vector as the problem's
        load = float(np.linalg.norm(self._gravity(params, posture.gravity(params.gravity_magnitude)).load))
        return self.options.rtol * (load if load > 0 else params.mu_breast * params.R**2)

    def remember_tangent(self, problem, position, factor):
        """Keep ``factor``, the exact Hessian of ``problem`` factorised at the equilibrium ``position``
        (by the solve's inertia check), for :meth:`tangent` to reuse.

        One factor per posture (slot) is kept, with the matrix its mixed-precision refinement needs:
        on ultra-thin about 10 MB a posture; on fine50k a few hundred MB (an estimate, not measured).
        :meth:`release_tangents` drops them.
        """
        self._tangents[problem.slot] = (problem.params, problem.acceleration, problem.smoothing,
                                        np.array(position, dtype=float), factor)

    def release_other_slots(self, slot):
        """Free the kept tangents and the numeric factors of every posture slot but ``slot`` (their symbolic
        analyses stay): a worker that solves one posture at a time then holds one posture's factors, as
        a serial run holds each posture's once."""
        self._tangents = {name: kept for name, kept in self._tangents.items() if name == slot}
        for (_, name), pattern in self._patterns.items():
            if name != slot:
                pattern.release_factors()

    def analyse_slots(self, fold_angle, postures):
        """PARDISO's symbolic analysis of each posture's pattern, now (before forking workers, which
        inherit it); nothing for the CG solver, which factorises nothing."""
        if self.options.method == "newton":
            for posture in postures:
                analyse(self.pattern(fold_angle, posture.name))

    def release_tangents(self):
        """Drop the factors kept by :meth:`remember_tangent` (their PARDISO memory stays with the
        posture's handle until its next factorisation or :meth:`after_fork`)."""
        self._tangents = {}

    def tangent(self, params, posture, position):
        """Exact free-dof Hessian at ``position``, factorised (for sensitivities).

        Where ``position`` is the last equilibrium solved for ``posture`` at ``params``, the
        factor of its inertia check is that matrix factorised already (:meth:`remember_tangent`),
        and is returned instead of a new one: the same matrix, the same factor.
        """
        problem = self.problem(params, posture)
        kept = self._tangents.get(posture.name)
        if kept is not None and kept[0] == params and np.array_equal(kept[1], problem.acceleration) \
                and kept[2] == problem.smoothing and np.array_equal(kept[3], position):
            return problem, kept[4]
        return problem, Factorization(problem.hessian(problem.free(position)), problem.pattern)

    def solve(self, params: Parameters, posture: Posture, start=None) -> PostureSolution:
        """Equilibrium of ``posture``; see :func:`solve_posture`."""
        return solve_posture(self, params, posture, start)

    def after_fork(self, keep_analyses=False):
        """In a forked child: drop the parent's kept tangents and, unless ``keep_analyses``, its PARDISO
        analyses, so that this process makes its own.

        With ``keep_analyses`` the child factorises on its copies of the parent's handles: the
        symbolic analysis the parent did (:meth:`solve_postures`) is not redone in every child
        (unless the parent's PARDISO ran on more than one thread: a child runs on one, and its handles
        redo an analysis made on another thread count).
        """
        self._tangents = {}
        if keep_analyses:
            return
        for assembler in self._assemblers.values():
            assembler._pattern = None
        self._patterns = {}

    def solve_postures(self, params: Parameters, postures, starts=None, processes=1) -> list[PostureSolution]:
        """Equilibria of several postures, optionally in ``processes`` forked worker processes.

        The postures are independent solves, so running them in parallel gives the
        same results bit for bit with a single-threaded PARDISO (the default; forked workers always
        run on one thread, so with ``BREASTCORE_PARDISO_THREADS`` > 1 the results differ from a serial
        run's by round-off, see :data:`breastcore.linalg.pardiso.PARDISO_THREADS_ENV`). ``starts`` maps a posture
        name to a warm start. Falls back to one process where ``fork`` is not
        available or this process may not have children (a daemon). Workers are forked at
        every call; an identification keeps its own (:class:`~breastcore.forward.workers.Workers`).

        Raises
        ------
        SolveError
            The first posture that failed (after all have run).
        """
        postures = list(postures)
        starts = starts or {}

        def solve(index):                                  # a SolveError is returned, so that all run
            try:
                return self.solve(params, postures[index], starts.get(postures[index].name))
            except SolveError as err:
                return err

        if (processes or 1) > 1:
            # the symbolic analyses, here once: each forked worker inherits them (on ultra-thin 25 ms
            # a posture, which every worker of every call redid before; on one PARDISO thread only)
            self.analyse_slots(params.fold_angle, postures)
        return raise_first_failure(fork_map(solve, len(postures), processes or 1,
                                            after_fork=functools.partial(self.after_fork, keep_analyses=True)))
