"""The gravity term J³ and the Chassaignac sliding term J⁴ on the back plane (paper, section 4.1)."""

from __future__ import annotations

import copy

import numpy as np

from breastcore.fem import kernels
from breastcore.fem.element_ops import _dot


class Gravity:
    """Gravity potential ``−Σ_τ |τ|/4 ρ a_g·(f_1+f_2+f_3+f_4)`` (paper, section 4.1).

    Parameters
    ----------
    reference : (N, 3) array
    tets : (T, 4) int array
    density : float
        ρ, kg m⁻³.
    acceleration : (3,) array
        ``a_g`` in the torso frame, m s⁻².
    """

    connectivity = None

    def __init__(self, reference, tets, density, acceleration):
        edges = reference[tets[:, 1:]] - reference[tets[:, :1]]
        volume = np.linalg.det(edges) / 6.0
        mass = np.zeros(len(reference))
        np.add.at(mass, tets, np.repeat(density * np.abs(volume)[:, None] / 4.0, 4, axis=1))
        self.nodal_mass = mass
        self.load = mass[:, None] * np.asarray(acceleration, dtype=float)[None, :]

    def with_acceleration(self, acceleration) -> "Gravity":
        """The same nodal masses under another acceleration ``a_g`` (m s⁻²)."""
        term = copy.copy(self)
        term.load = self.nodal_mass[:, None] * np.asarray(acceleration, dtype=float)[None, :]
        return term

    def admissible(self, x):
        return True

    def value(self, x):
        return -float(np.sum(self.load * x))

    def gradient(self, x):
        return -self.load.copy()


class Chassaignac:
    """Smoothed Chassaignac sliding energy ``Σ_n w_n (sqrt(|f_n−P_n|²+δ²) − δ)`` on Γ_B.

    The nodal weights are ``w_n = c Σ_{T∋n} |T|/3`` over the back triangles, which
    is the paper's ``Σ_T |T|/3 c Σ ||f(P)−P||`` with the norm smoothed (spec §2).

    Parameters
    ----------
    reference : (N, 3) array
    triangles : (B, 3) int array
        Back triangles Γ_B.
    coefficient : float
        c, Pa.
    smoothing : float
        δ, m.
    """

    def __init__(self, reference, triangles, coefficient, smoothing):
        nodes = np.unique(triangles)
        self.connectivity = nodes[:, None]
        area = 0.5 * np.linalg.norm(np.cross(reference[triangles[:, 1]] - reference[triangles[:, 0]],
                                             reference[triangles[:, 2]] - reference[triangles[:, 0]]), axis=1)
        weight = np.zeros(len(reference))
        np.add.at(weight, triangles, np.repeat(area[:, None] / 3.0, 3, axis=1))
        self.weight = coefficient * weight[nodes]
        self.anchor = reference[nodes]
        self.smoothing = float(smoothing)

    def with_smoothing(self, smoothing) -> "Chassaignac":
        """The same weights and anchors with another smoothing length δ (m)."""
        term = copy.copy(self)
        term.smoothing = float(smoothing)
        return term

    def admissible(self, x):
        return True

    def _slip(self, x):
        u = x[self.connectivity[:, 0]] - self.anchor
        value, root = kernels.smoothed_norm(u, self.smoothing)
        return u, value, root

    def value(self, x):
        return _dot(self.weight, self._slip(x)[1])

    def gradient(self, x):
        u, _, root = self._slip(x)
        out = np.zeros_like(x)
        out[self.connectivity[:, 0]] = (self.weight / root)[:, None] * u
        return out

    def element_hessians(self, x):
        u, _, root = self._slip(x)
        eye = np.eye(3)[None]
        H = eye / root[:, None, None] - np.einsum("ni,nj->nij", u, u) / root[:, None, None] ** 3
        return self.weight[:, None, None] * H

    def projected_element_hessians(self, x):
        """:meth:`element_hessians`: these blocks are positive definite already."""
        return self.element_hessians(x)
