"""The compressible neo-Hookean bulk term J¹ (paper, section 4.1)."""

from __future__ import annotations

import copy

import numpy as np

from breastcore.fem import compiled, compiled_geometry, kernels, material
from breastcore.fem.element_ops import _cofactor


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
    loops over the tets (:mod:`breastcore.fem.compiled`), with ``det F`` and ``F⁻¹`` from
    the cofactor matrix in closed form; the Hessian goes straight into the CSR data.
    The numpy versions (:meth:`element_energies`, :meth:`element_gradients`,
    :meth:`element_hessians`, :meth:`projected_element_hessians`: blocks built by
    broadcasting) are the reference the compiled loops are tested against.
    """

    def __init__(self, reference, tets, lam, mu):
        self.connectivity = np.asarray(tets)
        self.lam, self.mu = float(lam), float(mu)
        self.volume, self.shape_gradients = compiled_geometry.bulk_reference(
            np.ascontiguousarray(reference, dtype=float), np.ascontiguousarray(self.connectivity))
        if not np.all(self.volume > 0):
            raise ValueError("reference mesh has non-positive tetrahedra")

    def with_moduli(self, lam, mu) -> "BulkNeoHookean":
        """The same term on the same reference geometry with Lamé parameters ``(lam, mu)`` (Pa).

        Shares the reference arrays (volumes, shape gradients), which depend on the
        geometry only: building them is most of the constructor's cost.
        """
        term = copy.copy(self)
        term.lam, term.mu = float(lam), float(mu)
        return term

    def deformation_gradient(self, x):
        """``F`` of every tet, ``(T, 3, 3)``."""
        return np.matmul(np.swapaxes(x[self.connectivity], 1, 2), self.shape_gradients)

    def deformation_extremes(self, x):
        """``(min det F, max principal stretch)`` over the tets at ``x`` (compiled:
        :func:`breastcore.fem.compiled_geometry.deformation_extremes`)."""
        min_det, stretch = compiled_geometry.deformation_extremes(
            np.ascontiguousarray(x, dtype=float), self.connectivity, self.shape_gradients)
        return float(min_det), float(stretch)

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
        """Energy in J (``+inf`` if a tet is inverted); compiled (:func:`breastcore.fem.compiled.bulk_energy`)."""
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
        (:func:`breastcore.fem.material.tangent_modulus`).
        """
        F = self.deformation_gradient(x)
        return material.tangent_modulus(F, self.lam, self.mu).reshape(len(F), 9, 9)

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
        # |τ| ∇N_a·∇N_b: the constant part of the μ δ_ik block.
        diagonal = self.mu * np.einsum("naj,nbj->nab", self.shape_gradients, self.shape_gradients) \
            * self.volume[:, None, None]
        for i in range(3):
            H[:, :, i, :, i] += diagonal
        return H.reshape(n, 12, 12)
