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

import copy

import numpy as np

from . import compiled, kernels
from .assembly import element_dofs

#: Edge-to-node map of a triangle: edge a = Σ_n S[a, n] x_n.
_TRIANGLE_EDGES = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])


def _dot(a, b):
    """``a · b`` of two vectors without BLAS.

    numpy's OpenBLAS splits a dot product of more than 10 000 entries over threads;
    when the other core is busy (two jobs on a 2-core machine) each call then waits
    for a scheduler tick, 4-8 ms instead of 10 µs.
    """
    return float(np.einsum("i,i->", a, b))


def _scatter(dofs, element_values, shape):
    """Sum per-element ``(n, k, 3)`` nodal values into an array of ``shape`` (one bincount)."""
    size = int(np.prod(shape))
    return np.bincount(dofs.ravel(), weights=element_values.ravel(), minlength=size).reshape(shape)


def _edges_to_nodes(values, axis):
    """Apply ``_TRIANGLE_EDGES``ᵀ on ``axis`` (length 2, edges) to give length 3 (nodes).

    Edge ``a`` is ``x_{a+1} − x_0``, so node 0 receives ``−(v_0 + v_1)`` and node ``a+1`` receives ``v_a``.
    """
    v = np.moveaxis(values, axis, 0)
    out = np.empty((3,) + v.shape[1:])
    out[0] = -(v[0] + v[1])
    out[1:] = v
    return np.moveaxis(out, 0, axis)


def _cofactor(F):
    """Cofactor matrices ``J F⁻ᵀ`` and determinants ``J`` of ``(n, 3, 3)`` matrices, in closed form."""
    a, b, c = F[:, 0, 0], F[:, 0, 1], F[:, 0, 2]
    d, e, f = F[:, 1, 0], F[:, 1, 1], F[:, 1, 2]
    g, h, i = F[:, 2, 0], F[:, 2, 1], F[:, 2, 2]
    cof = np.empty_like(F)
    cof[:, 0, 0] = e * i - f * h
    cof[:, 0, 1] = f * g - d * i
    cof[:, 0, 2] = d * h - e * g
    cof[:, 1, 0] = c * h - b * i
    cof[:, 1, 1] = a * i - c * g
    cof[:, 1, 2] = b * g - a * h
    cof[:, 2, 0] = b * f - c * e
    cof[:, 2, 1] = c * d - a * f
    cof[:, 2, 2] = a * e - b * d
    J = a * cof[:, 0, 0] + b * cof[:, 0, 1] + c * cof[:, 0, 2]
    return cof, J


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

    Notes
    -----
    Performance: :meth:`value`, :meth:`gradient`, :meth:`scatter_hessian` and
    :meth:`scatter_projected_hessian` (what a Newton iteration calls) are compiled
    loops over the tets (:mod:`breastcore.compiled`), with ``det F`` and ``F⁻¹`` from
    the cofactor matrix in closed form; the Hessian goes straight into the CSR data.
    The numpy versions (:meth:`element_energies`, :meth:`element_gradients`,
    :meth:`element_hessians`, :meth:`projected_element_hessians`: blocks built by
    broadcasting) are the reference the compiled loops are tested against.
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
        # |τ| ∇N_a·∇N_b: the constant part of the μ δ_ik block.
        self._volume_GG = np.einsum("naj,nbj->nab", self.shape_gradients, self.shape_gradients) \
            * self.volume[:, None, None]

    def deformation_gradient(self, x):
        """``F`` of every tet, ``(T, 3, 3)``."""
        return np.matmul(np.swapaxes(x[self.connectivity], 1, 2), self.shape_gradients)

    def det_F(self, x):
        return _cofactor(self.deformation_gradient(x))[1]

    def admissible(self, x):
        return bool(np.all(self.det_F(x) > 0))

    def _kinematics(self, x):
        F = self.deformation_gradient(x)
        cof, J = _cofactor(F)
        trace_C = np.einsum("nij,nij->n", F, F)
        return F, J, trace_C, cof

    def value(self, x):
        """Energy in J (``+inf`` if a tet is inverted); compiled (:func:`breastcore.compiled.bulk_energy`)."""
        return compiled.bulk_energy(np.ascontiguousarray(x, dtype=float), self.connectivity, self.shape_gradients,
                                    self.volume, self.lam, self.mu)

    checked_value = value

    def _spatial_gradients(self, cof, J):
        # Q_a = ∇N_a F⁻¹ with F⁻¹ = cof(F)ᵀ / J
        return np.matmul(self.shape_gradients, np.swapaxes(cof, 1, 2)) / J[:, None, None]

    def gradient(self, x):
        out = np.zeros(np.shape(x))
        compiled.add_bulk_gradient(out, np.ascontiguousarray(x, dtype=float), self.connectivity,
                                   self.shape_gradients, self.volume, self.lam, self.mu)
        return out

    def element_gradients(self, x):
        """Reference numpy version of :meth:`gradient`: per-tet nodal forces ``(T, 4, 3)``, N."""
        F, J, trace_C, cof = self._kinematics(x)
        _, c_inv, _, _ = kernels.bulk_neo_hookean(J, trace_C, self.lam, self.mu)
        Q = self._spatial_gradients(cof, J)
        g_el = self.mu * np.matmul(self.shape_gradients, np.swapaxes(F, 1, 2)) + c_inv[:, None, None] * Q
        return g_el * self.volume[:, None, None]

    def element_energies(self, x):
        """Reference numpy version of :meth:`value`: ``|τ| W(F_τ)`` per tet ``(T,)``, J (NaN if inverted)."""
        F, J, trace_C, _ = self._kinematics(x)
        with np.errstate(invalid="ignore"):
            return self.volume * kernels.bulk_neo_hookean(J, trace_C, self.lam, self.mu)[0]

    def scatter_hessian(self, data, positions, x):
        """Add :meth:`element_hessians` into CSR ``data`` at ``positions`` (compiled, no blocks)."""
        compiled.scatter_bulk_hessian(data, positions, np.ascontiguousarray(x, dtype=float), self.connectivity,
                                      self.shape_gradients, self.volume, self.lam, self.mu)

    def scatter_projected_hessian(self, data, positions, x):
        """Add :meth:`projected_element_hessians` into CSR ``data`` (compiled, analytic eigensystem)."""
        compiled.scatter_bulk_hessian_projected(data, positions, np.ascontiguousarray(x, dtype=float),
                                                self.connectivity, self.shape_gradients, self.volume, self.lam,
                                                self.mu)

    def tangent_moduli(self, x):
        r"""``C = ∂²W/∂F²`` of every tet, ``(T, 9, 9)`` in Pa, rows and columns ``vec F`` (row-major).

        ``C_{ij,kl} = μ δ_ik δ_jl + c_swap F⁻¹_li F⁻¹_jk + c_vol F⁻¹_ji F⁻¹_lk``
        (:func:`breastcore.kernels.bulk_neo_hookean`).
        """
        F, J, trace_C, cof = self._kinematics(x)
        _, _, c_swap, c_vol = kernels.bulk_neo_hookean(J, trace_C, self.lam, self.mu)
        Finv = np.swapaxes(cof, 1, 2) / J[:, None, None]
        C = self.mu * np.einsum("ik,jl->ijkl", np.eye(3), np.eye(3))[None] \
            + c_swap[:, None, None, None, None] * np.einsum("nli,njk->nijkl", Finv, Finv) \
            + c_vol[:, None, None, None, None] * np.einsum("nji,nlk->nijkl", Finv, Finv)
        return C.reshape(len(F), 9, 9)

    def projected_element_hessians(self, x):
        r"""Reference numpy version of the PSD-projected blocks ``(T, 12, 12)``.

        Notes
        -----
        The block is ``|τ| Bᵀ C⁺ B`` where ``C⁺`` is :meth:`tangent_moduli` with its
        negative eigenvalues set to zero (numerical ``eigh`` here; the compiled
        :meth:`scatter_projected_hessian` uses the analytic eigensystem) and
        ``(B x_e)_{ij} = Σ_a x_{ai} ∂_j N_a``. Since ``B`` has rank 9, the block is
        PSD, and equals :meth:`element_hessians` where ``C`` is PSD already.
        """
        lam_C, vec_C = np.linalg.eigh(self.tangent_moduli(x))
        C = np.einsum("nij,nj,nkj->nik", vec_C, np.maximum(lam_C, 0.0), vec_C).reshape(-1, 3, 3, 3, 3)
        G = self.shape_gradients
        H = np.einsum("naj,nijkl,nbl->naibk", G, C, G) * self.volume[:, None, None, None, None]
        return H.reshape(len(G), 12, 12)

    def element_hessians(self, x):
        F, J, trace_C, cof = self._kinematics(x)
        _, _, c_swap, c_vol = kernels.bulk_neo_hookean(J, trace_C, self.lam, self.mu)
        Q = self._spatial_gradients(cof, J)
        n = len(F)
        # c_vol Q_ai Q_bk + c_swap Q_bi Q_ak + μ δ_ik ∇N_a·∇N_b, all times |τ|
        H = (Q * (self.volume * c_vol)[:, None, None])[:, :, :, None, None] * Q[:, None, None, :, :]
        swap = (Q * (self.volume * c_swap)[:, None, None])[:, :, :, None, None] * Q[:, None, None, :, :]
        H += swap.transpose(0, 3, 2, 1, 4)
        diagonal = self.mu * self._volume_GG
        for i in range(3):
            H[:, :, i, :, i] += diagonal
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
        self.thickness = float(thickness)
        E = _TRIANGLE_EDGES @ reference[self.connectivity]                  # (S,2,3)
        G = np.einsum("nai,nbi->nab", E, E)
        self.det_G = np.linalg.det(G)
        self.G_inv = np.linalg.inv(G)
        self.area = 0.5 * np.sqrt(self.det_G)
        self._dofs = element_dofs(self.connectivity)

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
        return _dot(self.area, W)

    def checked_value(self, x):
        """``value(x)``, or ``+inf`` if a skin triangle is degenerate (one pass instead of two)."""
        _, _, D, I1 = self._edges(x)
        if not np.all(D / self.det_G > 1e-12):
            return np.inf
        W = kernels.membrane_neo_hookean(I1, D, self.det_G, self.lam, self.mu)[0]
        return _dot(self.area, W)

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
        return _scatter(self._dofs, _edges_to_nodes(dW, 1), x.shape)

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
        :meth:`breastcore.assembly.FreeDofAssembler.assemble_terms`.
        """
        return tuple(term for term in self.terms if term.connectivity is not None)


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
