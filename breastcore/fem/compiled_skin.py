r"""Compiled (numba) loops for the skin membrane: its energy, gradient and Hessian scatter.

The numpy versions in :class:`~breastcore.fem.skin.SkinMembrane` build ``(S, 2, 3)`` edge
arrays and ``(S, 9, 9)`` blocks by broadcasting: on ultra-thin (1,600 skin triangles) a
gradient took 1.3 ms and a Hessian 3 ms, as long as the compiled bulk loops over seven
times as many tets, and 14 % of an identification in all. These loops follow
:mod:`breastcore.fem.compiled`: one pass per call, the Hessian written straight into the
CSR data. The numpy versions stay the reference (``tests/fem/test_compiled.py``).

Per triangle, with edges ``e_a = x_{a+1} − x_0``, Gram matrix ``g_ab = e_a·e_b``,
``D = det g`` and ``I1 = G⁻¹ : g`` (:func:`breastcore.fem.kernels.membrane_neo_hookean`):

.. math::

    \frac{\partial W}{\partial e_a} = \mu\, G^{-1}_{ab} e_b + W_D\, \frac{\partial D}{\partial e_a},
    \qquad
    \frac{\partial^2 W}{\partial e_{ai}\partial e_{bj}} = \mu\, G^{-1}_{ab} \delta_{ij}
        + W_D \frac{\partial^2 D}{\partial e_{ai}\partial e_{bj}}
        + W_{DD} \frac{\partial D}{\partial e_{ai}} \frac{\partial D}{\partial e_{bj}},

and node 0 takes ``−(v_0 + v_1)`` of an edge quantity ``v``, node ``a + 1`` takes ``v_a``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from breastcore.fem import kernels

_membrane = njit(cache=True)(kernels.membrane_neo_hookean)

#: A skin triangle with ``det g / det G`` at or below this is degenerate (energy ``+inf``).
DEGENERATE_METRIC_RATIO = 1e-12


@njit(cache=True)
def _edges(e, g, x, triangle):
    """Edges ``e`` (2, 3) and their Gram matrix ``g`` (2, 2) of one triangle; returns ``D = det g``."""
    for a in range(2):
        for i in range(3):
            e[a, i] = x[triangle[a + 1], i] - x[triangle[0], i]
    for a in range(2):
        for b in range(2):
            g[a, b] = e[a, 0] * e[b, 0] + e[a, 1] * e[b, 1] + e[a, 2] * e[b, 2]
    return g[0, 0] * g[1, 1] - g[0, 1] * g[0, 1]


@njit(cache=True)
def _first_invariant(G_inv, g):
    return G_inv[0, 0] * g[0, 0] + 2.0 * G_inv[0, 1] * g[0, 1] + G_inv[1, 1] * g[1, 1]


@njit(cache=True)
def skin_energy(x, triangles, G_inv, det_G, area, lam, mu):
    """``Σ_T |T| W`` in J, or ``+inf`` if a triangle has ``det g / det G ≤`` :data:`DEGENERATE_METRIC_RATIO`."""
    e = np.empty((2, 3))
    g = np.empty((2, 2))
    total = 0.0
    for t in range(triangles.shape[0]):
        D = _edges(e, g, x, triangles[t])
        if not D / det_G[t] > DEGENERATE_METRIC_RATIO:
            return np.inf
        W = _membrane(_first_invariant(G_inv[t], g), D, det_G[t], lam, mu)[0]
        total += area[t] * W
    return total


@njit(cache=True)
def _metric_derivative(dD, e, g):
    """``dD`` (2, 3) = ∂D/∂e of one triangle."""
    for i in range(3):
        dD[0, i] = 2.0 * (g[1, 1] * e[0, i] - g[0, 1] * e[1, i])
        dD[1, i] = 2.0 * (g[0, 0] * e[1, i] - g[0, 1] * e[0, i])


@njit(cache=True)
def _edge_derivatives(dW, dD, e, g, G_inv, W_D, mu):
    """``dD`` (2, 3) = ∂D/∂e and ``dW`` (2, 3) = ∂W/∂e of one triangle."""
    _metric_derivative(dD, e, g)
    for i in range(3):
        for a in range(2):
            dW[a, i] = mu * (G_inv[a, 0] * e[0, i] + G_inv[a, 1] * e[1, i]) + W_D * dD[a, i]


@njit(cache=True)
def add_skin_gradient(out, x, triangles, G_inv, det_G, area, lam, mu):
    """Add ``∂/∂x Σ_T |T| W`` (N) into ``out`` (N, 3)."""
    e = np.empty((2, 3))
    g = np.empty((2, 2))
    dW = np.empty((2, 3))
    dD = np.empty((2, 3))
    for t in range(triangles.shape[0]):
        tri = triangles[t]
        D = _edges(e, g, x, tri)
        W_D = _membrane(_first_invariant(G_inv[t], g), D, det_G[t], lam, mu)[1]
        _edge_derivatives(dW, dD, e, g, G_inv[t], W_D, mu)
        A = area[t]
        for i in range(3):
            out[tri[0], i] -= A * (dW[0, i] + dW[1, i])
            out[tri[1], i] += A * dW[0, i]
            out[tri[2], i] += A * dW[1, i]


@njit(cache=True)
def scatter_skin_hessian(data, positions, x, triangles, G_inv, det_G, area, lam, mu):
    """Add the skin Hessian of every triangle into the CSR ``data`` at ``positions`` (S, 9, 9), ``-1`` dropped."""
    e = np.empty((2, 3))
    g = np.empty((2, 2))
    dD = np.empty((2, 3))
    He = np.empty((2, 3, 2, 3))                                  # ∂²W/∂e∂e
    Hn = np.empty((3, 3, 3, 3))                                  # on the nodes
    for t in range(triangles.shape[0]):
        D = _edges(e, g, x, triangles[t])
        _, W_D, W_DD = _membrane(_first_invariant(G_inv[t], g), D, det_G[t], lam, mu)
        _metric_derivative(dD, e, g)                              # ∂W/∂e itself is not needed here
        for i in range(3):
            for j in range(3):
                delta = 1.0 if i == j else 0.0
                d00 = 2.0 * g[1, 1] * delta - 2.0 * e[1, i] * e[1, j]
                d11 = 2.0 * g[0, 0] * delta - 2.0 * e[0, i] * e[0, j]
                d01 = 4.0 * e[0, i] * e[1, j] - 2.0 * e[1, i] * e[0, j] - 2.0 * g[0, 1] * delta
                d10 = 4.0 * e[0, j] * e[1, i] - 2.0 * e[1, j] * e[0, i] - 2.0 * g[0, 1] * delta
                He[0, i, 0, j] = mu * G_inv[t, 0, 0] * delta + W_D * d00 + W_DD * dD[0, i] * dD[0, j]
                He[1, i, 1, j] = mu * G_inv[t, 1, 1] * delta + W_D * d11 + W_DD * dD[1, i] * dD[1, j]
                He[0, i, 1, j] = mu * G_inv[t, 0, 1] * delta + W_D * d01 + W_DD * dD[0, i] * dD[1, j]
                He[1, i, 0, j] = mu * G_inv[t, 1, 0] * delta + W_D * d10 + W_DD * dD[1, i] * dD[0, j]
        A = area[t]
        for i in range(3):
            for j in range(3):
                h00, h01 = He[0, i, 0, j], He[0, i, 1, j]
                h10, h11 = He[1, i, 0, j], He[1, i, 1, j]
                Hn[0, i, 0, j] = A * (h00 + h01 + h10 + h11)
                Hn[0, i, 1, j] = -A * (h00 + h10)
                Hn[0, i, 2, j] = -A * (h01 + h11)
                Hn[1, i, 0, j] = -A * (h00 + h01)
                Hn[2, i, 0, j] = -A * (h10 + h11)
                Hn[1, i, 1, j] = A * h00
                Hn[1, i, 2, j] = A * h01
                Hn[2, i, 1, j] = A * h10
                Hn[2, i, 2, j] = A * h11
        for n in range(3):
            for i in range(3):
                for m in range(3):
                    for j in range(3):
                        p = positions[t, 3 * n + i, 3 * m + j]
                        if p >= 0:
                            data[p] += Hn[n, i, m, j]
