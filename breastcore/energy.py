"""The four terms of the paper's discrete energy ``J_h`` and their composite.

Every term exposes, for node positions ``x`` of shape ``(N, 3)`` in metres:

- ``value(x)``: energy in J (a float);
- ``gradient(x)``: ``(N, 3)`` array in N;
- ``element_hessians(x)``: ``(n, 3k, 3k)`` array in N m⁻¹, one block per element
  of ``connectivity`` (``(n, k)`` node indices), dof order ``(node, xyz)``;
- ``admissible(x)``: False where the energy is +∞ (an inverted tet or a
  degenerate skin triangle), so a line search can reject the step.

The composite sums terms; sparse assembly lives in :mod:`breastcore.assembly`.
"""

from __future__ import annotations

import numpy as np

from . import kernels

#: Edge-to-node map of a triangle: edge a = Σ_n S[a, n] x_n.
_TRIANGLE_EDGES = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])


class BulkNeoHookean:
    """Neo-Hookean bulk on P1 tetrahedra: ``Σ_τ |τ| W(F_τ)`` (spec §2).

    Parameters
    ----------
    reference : (N, 3) array
        Gravity-free node positions, m.
    tets : (T, 4) int array
        Positively oriented tetrahedra.
    lam, mu : float
        Lamé parameters, Pa.
    """

    def __init__(self, reference, tets, lam, mu):
        self.connectivity = np.asarray(tets)
        self.lam, self.mu = float(lam), float(mu)
        edges = reference[tets[:, 1:]] - reference[tets[:, :1]]          # (T,3 edges,3)
        Dm = np.swapaxes(edges, 1, 2)                                     # columns = edges
        self.volume = np.linalg.det(Dm) / 6.0
        if np.any(self.volume <= 0):
            raise ValueError("reference mesh has non-positive tetrahedra")
        Dm_inv = np.linalg.inv(Dm)
        self.shape_gradients = np.concatenate([-Dm_inv.sum(axis=1, keepdims=True), Dm_inv], axis=1)

    def deformation_gradient(self, x):
        """``F`` of every tet, ``(T, 3, 3)``."""
        return np.einsum("nai,naj->nij", x[self.connectivity], self.shape_gradients)

    def det_F(self, x):
        return np.linalg.det(self.deformation_gradient(x))

    def admissible(self, x):
        return bool(np.all(self.det_F(x) > 0))

    def _kinematics(self, x):
        F = self.deformation_gradient(x)
        J = np.linalg.det(F)
        trace_C = np.einsum("nij,nij->n", F, F)
        return F, J, trace_C

    def value(self, x):
        F, J, trace_C = self._kinematics(x)
        W = kernels.bulk_neo_hookean(J, trace_C, self.lam, self.mu)[0]
        return float(self.volume @ W)

    def _spatial_gradients(self, F):
        return self.shape_gradients @ np.linalg.inv(F)                    # Q_a = ∇N_a F⁻¹

    def gradient(self, x):
        F, J, trace_C = self._kinematics(x)
        _, c_inv, _, _ = kernels.bulk_neo_hookean(J, trace_C, self.lam, self.mu)
        Q = self._spatial_gradients(F)
        g_el = self.mu * np.einsum("nij,naj->nai", F, self.shape_gradients) + c_inv[:, None, None] * Q
        g_el *= self.volume[:, None, None]
        out = np.zeros_like(x)
        np.add.at(out, self.connectivity, g_el)
        return out

    def element_hessians(self, x):
        F, J, trace_C = self._kinematics(x)
        _, _, c_swap, c_vol = kernels.bulk_neo_hookean(J, trace_C, self.lam, self.mu)
        Q = self._spatial_gradients(F)
        Gs = self.shape_gradients
        n = len(F)
        H = np.zeros((n, 4, 3, 4, 3))
        GG = np.einsum("naj,nbj->nab", Gs, Gs) * self.mu
        idx = np.arange(3)
        H[:, :, idx, :, idx] = GG[None]                                     # μ δ_ik (∇N_a·∇N_b)
        H += c_swap[:, None, None, None, None] * np.einsum("nbi,nak->naibk", Q, Q)
        H += c_vol[:, None, None, None, None] * np.einsum("nai,nbk->naibk", Q, Q)
        H *= self.volume[:, None, None, None, None]
        return H.reshape(n, 12, 12)


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
    """

    def __init__(self, reference, triangles, lam, mu, thickness):
        self.connectivity = np.asarray(triangles)
        self.lam, self.mu = float(lam) * thickness, float(mu) * thickness
        E = _TRIANGLE_EDGES @ reference[self.connectivity]                  # (S,2,3)
        G = np.einsum("nai,nbi->nab", E, E)
        self.det_G = np.linalg.det(G)
        self.G_inv = np.linalg.inv(G)
        self.area = 0.5 * np.sqrt(self.det_G)

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
        return bool(np.all(self.metric_ratio(x) > 1e-12))

    def value(self, x):
        _, _, D, I1 = self._edges(x)
        W = kernels.membrane_neo_hookean(I1, D, self.det_G, self.lam, self.mu)[0]
        return float(self.area @ W)

    def _edge_gradient(self, e, g, D, I1):
        _, W_D, W_DD = kernels.membrane_neo_hookean(I1, D, self.det_G, self.lam, self.mu)
        # dD/de_1 = 2(|e_2|² e_1 − (e_1·e_2) e_2), dD/de_2 = 2(|e_1|² e_2 − (e_1·e_2) e_1)
        dD = 2.0 * np.stack([g[:, 1, 1, None] * e[:, 0] - g[:, 0, 1, None] * e[:, 1],
                             g[:, 0, 0, None] * e[:, 1] - g[:, 0, 1, None] * e[:, 0]], axis=1)
        dW = self.mu * np.einsum("nab,nbi->nai", self.G_inv, e) + W_D[:, None, None] * dD
        return dW, dD, W_D, W_DD

    def gradient(self, x):
        e, g, D, I1 = self._edges(x)
        dW = self._edge_gradient(e, g, D, I1)[0] * self.area[:, None, None]
        out = np.zeros_like(x)
        np.add.at(out, self.connectivity, np.einsum("an,sai->sni", _TRIANGLE_EDGES, dW))
        return out

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
        H_nodes = np.einsum("am,naibj,bk->nmikj", _TRIANGLE_EDGES, H, _TRIANGLE_EDGES)
        return H_nodes.reshape(n, 9, 9)


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

    def admissible(self, x):
        return True

    def _slip(self, x):
        u = x[self.connectivity[:, 0]] - self.anchor
        value, root = kernels.smoothed_norm(u, self.smoothing)
        return u, value, root

    def value(self, x):
        return float(self.weight @ self._slip(x)[1])

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


class Composite:
    """Sum of energy terms; ``J_h = J¹ + J² + J³ + J⁴`` (paper, section 4.1)."""

    def __init__(self, terms):
        self.terms = tuple(terms)

    def value(self, x):
        """Energy in J, or ``+inf`` if the configuration is inadmissible."""
        if not self.admissible(x):
            return np.inf
        return sum(term.value(x) for term in self.terms)

    def admissible(self, x):
        return all(term.admissible(x) for term in self.terms)

    def gradient(self, x):
        return sum(term.gradient(x) for term in self.terms)

    def hessian_blocks(self, x, project=False):
        """``[(connectivity, element_hessians)]`` of the non-linear terms.

        With ``project=True`` each bulk and skin block is projected to the nearest
        positive semi-definite matrix (eigenvalues clamped at 0); the Chassaignac
        blocks are positive definite already.
        """
        blocks = []
        for term in self.terms:
            if term.connectivity is None:
                continue
            H = term.element_hessians(x)
            if project and not isinstance(term, Chassaignac):
                H = project_psd(H)
            blocks.append((term.connectivity, H))
        return blocks


def project_psd(blocks):
    """Make each symmetric block ``(n, m, m)`` positive semi-definite.

    Negative eigenvalues are clamped to zero (Teran et al. 2005; the absolute-value
    filter of Chen et al. 2024 took 8× more iterations here); positive blocks are
    returned unchanged.
    """
    w, V = np.linalg.eigh(blocks)
    negative = np.any(w < 0, axis=1)
    if not np.any(negative):
        return blocks
    out = blocks.copy()
    Vn = V[negative]
    out[negative] = np.einsum("nij,nj,nkj->nik", Vn, np.maximum(w[negative], 0.0), Vn)
    return out
