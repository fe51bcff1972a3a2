"""The neo-Hookean skin membrane term J² (paper, section 4.1)."""

from __future__ import annotations

import copy

import numpy as np

from breastcore.fem import compiled_skin, kernels
from breastcore.fem.element_ops import _TRIANGLE_EDGES, _edges_to_nodes, project_psd


class SkinMembrane:
    """Neo-Hookean skin membrane on the skin triangles: ``Σ_T |T| t_s W(A_T)`` (spec §2).

    Parameters
    ----------
    reference : (N, 3) array
        Gravity-free node positions, m.
    triangles : (S, 3) int array
        Skin triangles Γ_F.
    lam, mu : float
        Skin Lamé parameters λ_s, μ_s, Pa.
    thickness : float
        Skin thickness t_s, m; the membrane moduli are ``λ_s t_s`` and ``μ_s t_s`` (N/m).

    Notes
    -----
    Performance: :meth:`value`, :meth:`checked_value`, :meth:`gradient` and
    :meth:`scatter_hessian` (what a Newton iteration calls) are compiled loops over the
    triangles (:mod:`breastcore.fem.compiled_skin`). The numpy versions
    (:meth:`element_energies`, :meth:`element_gradients`, :meth:`element_hessians`) are
    the reference they are tested against.
    """

    def __init__(self, reference, triangles, lam, mu, thickness):
        self.connectivity = np.asarray(triangles)
        self.lam, self.mu = float(lam) * thickness, float(mu) * thickness
        self.thickness = float(thickness)
        E = _TRIANGLE_EDGES @ reference[self.connectivity]                  # (S,2,3)
        G = np.einsum("nai,nbi->nab", E, E)
        self.det_G = np.linalg.det(G)
        self.G_inv = np.linalg.inv(G)
        self.area = 0.5 * np.sqrt(self.det_G)

    def with_moduli(self, lam, mu, thickness) -> "SkinMembrane":
        """The same term on the same reference triangles with ``λ_s, μ_s`` (Pa) and ``t_s`` (m).

        Shares the reference metrics (``G⁻¹``, ``det G``, areas), which depend on the geometry only.
        """
        term = copy.copy(self)
        term.lam, term.mu = float(lam) * thickness, float(mu) * thickness
        term.thickness = float(thickness)
        return term

    def _edges(self, x):
        e = _TRIANGLE_EDGES @ x[self.connectivity]
        g = np.einsum("nai,nbi->nab", e, e)
        D = g[:, 0, 0] * g[:, 1, 1] - g[:, 0, 1] ** 2
        I1 = np.einsum("nab,nab->n", self.G_inv, g)
        return e, g, D, I1

    def metric_ratio(self, x):
        """``det g / det G = (det A)²`` per triangle (the squared area stretch)."""
        return self._edges(x)[2] / self.det_G

    def admissible(self, x):
        return bool(np.all(self.metric_ratio(x) > compiled_skin.DEGENERATE_METRIC_RATIO))

    def _compiled_args(self, x):
        return (np.ascontiguousarray(x, dtype=float), self.connectivity, self.G_inv, self.det_G, self.area,
                self.lam, self.mu)

    def value(self, x):
        """Energy in J, ``+inf`` if a triangle is degenerate (compiled:
        :func:`~breastcore.fem.compiled_skin.skin_energy`)."""
        return compiled_skin.skin_energy(*self._compiled_args(x))

    #: One pass gives the energy and the degeneracy test (``Composite.value`` calls this).
    checked_value = value

    def element_energies(self, x):
        """Reference numpy version of :meth:`value`: ``|T| W`` per triangle ``(S,)``, J."""
        _, _, D, I1 = self._edges(x)
        return self.area * kernels.membrane_neo_hookean(I1, D, self.det_G, self.lam, self.mu)[0]

    def _edge_gradient(self, e, g, D, I1):
        _, W_D, W_DD = kernels.membrane_neo_hookean(I1, D, self.det_G, self.lam, self.mu)
        # dD/de_1 = 2(|e_2|² e_1 − (e_1·e_2) e_2), dD/de_2 = 2(|e_1|² e_2 − (e_1·e_2) e_1)
        dD = 2.0 * np.stack([g[:, 1, 1, None] * e[:, 0] - g[:, 0, 1, None] * e[:, 1],
                             g[:, 0, 0, None] * e[:, 1] - g[:, 0, 1, None] * e[:, 0]], axis=1)
        dW = self.mu * np.einsum("nab,nbi->nai", self.G_inv, e) + W_D[:, None, None] * dD
        return dW, dD, W_D, W_DD

    def gradient(self, x):
        """Nodal forces ``(N, 3)``, N (compiled: :func:`~breastcore.fem.compiled_skin.add_skin_gradient`)."""
        out = np.zeros(np.shape(x))
        compiled_skin.add_skin_gradient(out, *self._compiled_args(x))
        return out

    def element_gradients(self, x):
        """Reference numpy version of :meth:`gradient`: per-triangle nodal forces ``(S, 3, 3)``, N."""
        e, g, D, I1 = self._edges(x)
        return _edges_to_nodes(self._edge_gradient(e, g, D, I1)[0] * self.area[:, None, None], 1)

    def scatter_hessian(self, data, positions, x):
        """Add :meth:`element_hessians` into CSR ``data`` at ``positions`` (compiled, no blocks)."""
        compiled_skin.scatter_skin_hessian(data, positions, *self._compiled_args(x))

    def element_hessians(self, x):
        e, g, D, I1 = self._edges(x)
        _, dD, W_D, W_DD = self._edge_gradient(e, g, D, I1)
        n = len(e)
        eye = np.eye(3)
        e1, e2, e12 = e[:, 0], e[:, 1], g[:, 0, 1]
        outer = lambda u, v: np.einsum("ni,nj->nij", u, v)  # noqa: E731
        d2D = np.empty((n, 2, 3, 2, 3))
        d2D[:, 0, :, 0, :] = 2 * g[:, 1, 1, None, None] * eye - 2 * outer(e2, e2)
        d2D[:, 1, :, 1, :] = 2 * g[:, 0, 0, None, None] * eye - 2 * outer(e1, e1)
        d2D[:, 0, :, 1, :] = 4 * outer(e1, e2) - 2 * outer(e2, e1) - 2 * e12[:, None, None] * eye
        d2D[:, 1, :, 0, :] = np.swapaxes(d2D[:, 0, :, 1, :], 1, 2)
        H = self.mu * np.einsum("nab,ij->naibj", self.G_inv, eye)
        H += W_D[:, None, None, None, None] * d2D
        H += W_DD[:, None, None, None, None] * np.einsum("nai,nbj->naibj", dD, dD)
        H *= self.area[:, None, None, None, None]
        H_nodes = _edges_to_nodes(_edges_to_nodes(H, 1), 3)              # Sᵀ H S on both edge axes
        return H_nodes.reshape(n, 9, 9)

    def projected_element_hessians(self, x):
        """:meth:`element_hessians` with each block's negative eigenvalues set to zero (:func:`project_psd`)."""
        return project_psd(self.element_hessians(x))
