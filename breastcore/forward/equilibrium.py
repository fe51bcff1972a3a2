"""The discrete energy of one posture as a function of the free dofs: value, gradient, Hessian."""

from __future__ import annotations


import numpy as np

from breastcore.fem.sliding_dual import SlidingDual
from breastcore.fem.terms import Composite
from breastcore.model.parameters import Parameters


class EquilibriumProblem:
    """``J_h`` on the free dofs for one parameter set, gravity vector and δ, on the mesh of ``model``
    (a :class:`~breastcore.forward.model.ForwardModel`)."""

    def __init__(self, model, params: Parameters, acceleration, smoothing, sliding_dual=False, slot=None,
                 sliding_release=False):
        self.model, self.params, self.slot = model, params, slot
        self.acceleration, self.smoothing = np.asarray(acceleration, dtype=float), float(smoothing)
        self.reference = model.reference(params.R, params.H)
        self.assembler = model.assembler(params.fold_angle)
        bulk, skin, gravity, sliding = model.energy_terms(params, acceleration, smoothing)
        self.bulk, self.gravity = bulk, gravity
        self.energy = Composite([bulk, skin, gravity, sliding])
        #: The Chassaignac dual state of the Newton steps (None: steps with the exact Hessian).
        self.sliding_dual = SlidingDual(sliding) if sliding_dual else None
        #: Whether Newton's steps release sticking back nodes (:meth:`step_gradient`; needs ``sliding_dual``).
        self.sliding_release = bool(sliding_release and sliding_dual)
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

    def step_hessian(self, z, project=False):
        """The matrix of Newton's steps: :meth:`hessian`, with the primal-dual sliding blocks of
        :class:`~breastcore.fem.sliding_dual.SlidingDual` if ``sliding_dual`` (its dual state
        moves to ``z``). It equals :meth:`hessian` at an equilibrium reached by such steps only
        to the solve's tolerance: Jacobians and the inertia checks of the returned state use
        :meth:`hessian`; Newton's own ``negative_pivots`` are this matrix's (the sliding blocks
        are positive definite in both, so the two differ only near a zero eigenvalue, except after
        :meth:`step_gradient` released nodes: their blocks are singular along the slip, and a
        reported negative pivot may be the step matrix's alone; the inertia of the returned state is
        the exact Hessian's)."""
        if self.sliding_dual is None:
            return self.hessian(z, project)
        terms = tuple(self.sliding_dual if term is self.sliding_dual.term else term
                      for term in self.energy.nonlinear_terms)
        return self.assembler.assemble_terms(terms, self.full(z), project)

    def step_gradient(self, z, g, release=True):
        """The right-hand side of Newton's step at ``z``, where the gradient is ``g`` (free dofs, N).

        With ``sliding_release`` (and ``release``), the forces of the back nodes that
        :meth:`SlidingDual.release <breastcore.fem.sliding_dual.SlidingDual.release>` releases are
        saturated, and their blocks in :meth:`step_hessian` at ``z`` change with them. Where no node
        is released, or with ``release=False`` (which clears an earlier release), it is ``g`` itself
        (the same object)."""
        if not self.sliding_release:
            return g
        if not release:
            self.sliding_dual.clear_release()
            return g
        x = self.full(z)
        correction = self.sliding_dual.release(x, self.assembler.expand(g, np.zeros_like(x)))
        return g + self.free(correction) if correction.any() else g

    @property
    def pattern(self):
        """Sparsity pattern of :meth:`hessian` (its PARDISO symbolic analysis is reused); with a
        ``slot`` (a posture's name), the model's copy of that slot, with its own PARDISO handles."""
        if self.slot is None:
            return self.assembler.pattern
        return self.model.pattern(self.params.fold_angle, self.slot)
