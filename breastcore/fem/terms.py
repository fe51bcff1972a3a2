"""The four terms of the paper's discrete energy ``J_h`` and their composite.

Every term exposes, for node positions ``x`` of shape ``(N, 3)`` in metres:

- ``value(x)``: energy in J (a float);
- ``gradient(x)``: ``(N, 3)`` array in N;
- ``element_hessians(x)``: ``(n, 3k, 3k)`` array in N m⁻¹, one block per element
  of ``connectivity`` (``(n, k)`` node indices), dof order ``(node, xyz)``;
- ``admissible(x)``: False where the energy is +∞ (an inverted tet or a
  degenerate skin triangle), so a line search can reject the step.

The composite sums terms; sparse assembly lives in :mod:`breastcore.fem.assembly`.
"""

from __future__ import annotations

import copy

import numpy as np

from breastcore.fem.bulk import BulkNeoHookean
from breastcore.fem.element_ops import project_psd
from breastcore.fem.loads import Chassaignac, Gravity
from breastcore.fem.skin import SkinMembrane

__all__ = ["BulkNeoHookean", "SkinMembrane", "Gravity", "Chassaignac", "Composite", "modulus_gradient", "project_psd"]


def modulus_gradient(term, attribute, x):
    """``∂ gradient(x) / ∂ term.<attribute>`` (N per unit of the attribute), for a term linear in it.

    The bulk and skin energies are linear in their Lamé moduli (``lam``, ``mu``),
    so this is the gradient of a copy of the term with that modulus 1 and the other 0.
    """
    unit = copy.copy(term)
    unit.lam = unit.mu = 0.0
    setattr(unit, attribute, 1.0)
    return unit.gradient(x)


class Composite:
    """Sum of energy terms; ``J_h = J¹ + J² + J³ + J⁴`` (paper, section 4.1)."""

    def __init__(self, terms):
        self.terms = tuple(terms)

    def value(self, x):
        """Energy in J, or ``+inf`` if the configuration is inadmissible."""
        if not all(term.admissible(x) for term in self.terms if not hasattr(term, "checked_value")):
            return np.inf
        total = 0.0
        for term in self.terms:
            value = term.checked_value(x) if hasattr(term, "checked_value") else term.value(x)
            if value == np.inf:
                return np.inf
            total += value
        return total

    def admissible(self, x):
        return all(term.admissible(x) for term in self.terms)

    def gradient(self, x):
        return sum(term.gradient(x) for term in self.terms)

    @property
    def nonlinear_terms(self):
        """The terms with Hessian blocks (``connectivity`` not ``None``), in order.

        Each has ``element_hessians`` and ``projected_element_hessians`` (PSD: the
        bulk's tangent modulus and each skin block with their negative eigenvalues set
        to zero; the Chassaignac blocks are positive definite already), assembled by
        :meth:`breastcore.fem.assembly.FreeDofAssembler.assemble_terms`.
        """
        return tuple(term for term in self.terms if term.connectivity is not None)
