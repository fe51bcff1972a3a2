"""Compiled (numba) loops over the tets that are not the energy: reference geometry and diagnostics.

:func:`bulk_reference` builds a :class:`~breastcore.fem.bulk.BulkNeoHookean` term's
reference arrays, once per ``(R, H)`` a solve or a Jacobian visits (46 times in an ultra-thin
identification, 14 ms each with numpy's batched ``det`` and ``inv``);
:func:`deformation_extremes` gives every solve's ``min det F`` and largest stretch.
They reuse the 3 × 3 helpers of :mod:`breastcore.fem.compiled`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from breastcore.fem.compiled import _deformation_gradient, _det, _inverse, _jacobi_eigh3


@njit(cache=True)
def bulk_reference(reference, tets):
    r"""Reference volumes ``|τ|`` (T,) in m³ and shape gradients ``∇N_a`` (T, 4, 3) in m⁻¹ of every tet.

    With ``D_m`` the matrix whose columns are the edges ``X_b − X_0`` (b = 1, 2, 3),
    ``|τ| = det D_m / 6``, ``∇N_b`` is row ``b − 1`` of ``D_m⁻¹`` and ``∇N_0 = −Σ_b ∇N_b``.
    A volume ≤ 0 is returned as it is (the caller rejects the mesh).
    """
    n = tets.shape[0]
    volume = np.empty(n)
    shape_gradients = np.empty((n, 4, 3))
    Dm = np.empty((3, 3))
    Dm_inv = np.empty((3, 3))
    for e in range(n):
        tet = tets[e]
        for i in range(3):
            for b in range(3):
                Dm[i, b] = reference[tet[b + 1], i] - reference[tet[0], i]
        J = _det(Dm)
        volume[e] = J / 6.0
        if not J > 0.0:
            continue
        _inverse(Dm_inv, Dm)
        for j in range(3):
            shape_gradients[e, 0, j] = -(Dm_inv[0, j] + Dm_inv[1, j] + Dm_inv[2, j])
            for b in range(3):
                shape_gradients[e, b + 1, j] = Dm_inv[b, j]
    return volume, shape_gradients


@njit(cache=True)
def deformation_extremes(x, tets, shape_gradients):
    """``(min det F, max principal stretch)`` over the tets: the solve's diagnostics (dimensionless).

    The largest principal stretch is the square root of the largest eigenvalue of ``FᵀF``
    (:func:`_jacobi_eigh3`).
    """
    F = np.empty((3, 3))
    C = np.empty((3, 3))
    Q = np.empty((3, 3))
    w = np.empty(3)
    min_det, max_square = np.inf, 0.0
    for e in range(tets.shape[0]):
        _deformation_gradient(F, x, tets[e], shape_gradients[e])
        min_det = min(min_det, _det(F))
        for i in range(3):
            for j in range(3):
                C[i, j] = F[0, i] * F[0, j] + F[1, i] * F[1, j] + F[2, i] * F[2, j]
        _jacobi_eigh3(C, w, Q)
        max_square = max(max_square, w[0], w[1], w[2])
    return min_det, np.sqrt(max_square)
