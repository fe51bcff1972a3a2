"""Compiled (numba) loops for the Newton iteration's hot spots: the bulk energy, its gradient and Hessian.

The numpy versions build an ``(n, 3k, 3k)`` block array and scatter it with
``np.bincount``; on ultra-thin (12,000 tets) that is 13 ms of a 60 ms Newton
iteration. These loops write each element's entries straight into the CSR data
array of :class:`~breastcore.assembly.FreeDofAssembler`, through its position
table ``(n, 3k, 3k)`` (``-1`` for an entry on a fixed dof). They are single-threaded
on purpose: the workflow runs two jobs on two cores.

The numpy blocks (:meth:`BulkNeoHookean.element_hessians`) stay the reference:
``tests/test_compiled.py`` checks these loops against them entry by entry.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def scatter_blocks(data, positions, blocks):
    """``data[positions[e, r, c]] += blocks[e, r, c]`` for every entry with a position ≥ 0."""
    n, m, _ = blocks.shape
    for e in range(n):
        for r in range(m):
            for c in range(m):
                p = positions[e, r, c]
                if p >= 0:
                    data[p] += blocks[e, r, c]


@njit(cache=True)
def scatter_bulk_hessian(data, positions, x, tets, shape_gradients, volume, lam, mu):
    r"""Add the neo-Hookean bulk Hessian of every tet into ``data``.

    Parameters
    ----------
    data : (nnz,) float array
        CSR values, updated in place.
    positions : (T, 12, 12) int32 array
        Index in ``data`` of each block entry, dof order ``(node, xyz)``; ``-1`` to drop.
    x : (N, 3) array
        Node positions, m.
    tets : (T, 4) int array
    shape_gradients : (T, 4, 3) array
        Reference gradients ``∇N_a``, m⁻¹.
    volume : (T,) array
        Reference volumes, m³.
    lam, mu : float
        Lamé parameters, Pa.

    Notes
    -----
    Per tet, with ``Q_a = ∇N_a F⁻¹``, ``c_vol = λJ(2J−1)`` and ``c_swap = μ − λJ(J−1)``
    (:func:`breastcore.kernels.bulk_neo_hookean`):

    .. math::

        H_{ai,bk} = |τ| \left(c_{vol} Q_{ai} Q_{bk} + c_{swap} Q_{bi} Q_{ak}
            + μ\, δ_{ik}\, ∇N_a·∇N_b\right)
    """
    F = np.empty((3, 3))
    Finv = np.empty((3, 3))
    Q = np.empty((4, 3))
    for e in range(tets.shape[0]):
        G = shape_gradients[e]
        _deformation_gradient(F, x, tets[e], G)
        J = _inverse(Finv, F)
        for a in range(4):
            for j in range(3):
                Q[a, j] = G[a, 0] * Finv[0, j] + G[a, 1] * Finv[1, j] + G[a, 2] * Finv[2, j]
        V = volume[e]
        c_vol = V * lam * J * (2.0 * J - 1.0)
        c_swap = V * (mu - lam * J * (J - 1.0))
        for a in range(4):
            for b in range(4):
                diagonal = V * mu * (G[a, 0] * G[b, 0] + G[a, 1] * G[b, 1] + G[a, 2] * G[b, 2])
                for i in range(3):
                    for k in range(3):
                        p = positions[e, 3 * a + i, 3 * b + k]
                        if p >= 0:
                            h = c_vol * Q[a, i] * Q[b, k] + c_swap * Q[b, i] * Q[a, k]
                            if i == k:
                                h += diagonal
                            data[p] += h


@njit(cache=True)
def _deformation_gradient(F, x, tet, G):
    for i in range(3):
        for j in range(3):
            s = 0.0
            for a in range(4):
                s += x[tet[a], i] * G[a, j]
            F[i, j] = s


@njit(cache=True)
def bulk_energy(x, tets, shape_gradients, volume, lam, mu):
    r"""``Σ_τ |τ| W(F_τ)`` in J, or ``+inf`` if any tet has ``det F ≤ 0``.

    ``W = μ/2 (tr FᵀF − 3 − 2 ln J) + λ/2 (J − 1)²`` (:func:`breastcore.kernels.bulk_neo_hookean`).
    """
    F = np.empty((3, 3))
    total = 0.0
    for e in range(tets.shape[0]):
        _deformation_gradient(F, x, tets[e], shape_gradients[e])
        J = _det(F)
        if not J > 0.0:
            return np.inf
        trace_C = 0.0
        for i in range(3):
            for j in range(3):
                trace_C += F[i, j] * F[i, j]
        total += volume[e] * (0.5 * mu * (trace_C - 3.0 - 2.0 * np.log(J)) + 0.5 * lam * (J - 1.0) ** 2)
    return total


@njit(cache=True)
def add_bulk_gradient(out, x, tets, shape_gradients, volume, lam, mu):
    r"""Add ``∂/∂x Σ_τ |τ| W(F_τ)`` (N) into ``out`` (N, 3).

    Per tet the force on node ``a`` is ``|τ| P ∇N_a`` with
    ``P = μF + (λJ(J−1) − μ) F⁻ᵀ``, i.e. ``|τ| (μ F∇N_a + c_inv Q_a)``, ``Q_a = ∇N_a F⁻¹``.
    """
    F = np.empty((3, 3))
    Finv = np.empty((3, 3))
    for e in range(tets.shape[0]):
        G = shape_gradients[e]
        _deformation_gradient(F, x, tets[e], G)
        J = _inverse(Finv, F)
        V = volume[e]
        c_inv = lam * J * (J - 1.0) - mu
        for a in range(4):
            node = tets[e, a]
            for i in range(3):
                FG = F[i, 0] * G[a, 0] + F[i, 1] * G[a, 1] + F[i, 2] * G[a, 2]
                Q = G[a, 0] * Finv[0, i] + G[a, 1] * Finv[1, i] + G[a, 2] * Finv[2, i]
                out[node, i] += V * (mu * FG + c_inv * Q)


@njit(cache=True)
def _inverse(Finv, F):
    """``F⁻¹ = cof(F)ᵀ / det F`` into ``Finv``; returns ``det F``."""
    J = _det(F)
    Finv[0, 0] = (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]) / J
    Finv[1, 0] = (F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]) / J
    Finv[2, 0] = (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]) / J
    Finv[0, 1] = (F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]) / J
    Finv[1, 1] = (F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]) / J
    Finv[2, 1] = (F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]) / J
    Finv[0, 2] = (F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]) / J
    Finv[1, 2] = (F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]) / J
    Finv[2, 2] = (F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]) / J
    return J


@njit(cache=True)
def _det(F):
    """``det F`` of a 3×3 matrix, expanded along its first row."""
    return (F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
            + F[0, 1] * (F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2])
            + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]))
