"""Compiled (numba) loops for the Newton iteration's hot spots: the bulk energy, its gradient and Hessian.

The numpy versions build an ``(n, 3k, 3k)`` block array and scatter it with
``np.bincount``; on ultra-thin (12,000 tets) that is 13 ms of a 60 ms Newton
iteration. These loops write each element's entries straight into the CSR data
array of :class:`~breastcore.fem.assembly.FreeDofAssembler`, through its position
table ``(n, 3k, 3k)`` (``-1`` for an entry on a fixed dof). They are single-threaded
on purpose: the workflow runs two jobs on two cores.

The numpy blocks (:meth:`BulkNeoHookean.element_hessians`) stay the reference:
``tests/fem/test_compiled.py`` checks these loops against them entry by entry.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from breastcore.fem import material

# The material law, compiled (fem/material.py is its one definition).
_energy_density = njit(cache=True)(material.energy_density)
_stress_coefficient = njit(cache=True)(material.stress_coefficient)
_tangent_coefficients = njit(cache=True)(material.tangent_coefficients)
_pressure = njit(cache=True)(material.pressure)
_stretch_hessian_diagonal = njit(cache=True)(material.stretch_hessian_diagonal)
_stretch_hessian_off_diagonal = njit(cache=True)(material.stretch_hessian_off_diagonal)


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
    (:func:`breastcore.fem.kernels.bulk_neo_hookean`):

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
        c_swap, c_vol = _tangent_coefficients(J, lam, mu, V)
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

    ``W = μ/2 (tr FᵀF − 3 − 2 ln J) + λ/2 (J − 1)²`` (:func:`breastcore.fem.kernels.bulk_neo_hookean`).
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
        total += volume[e] * _energy_density(J, trace_C, lam, mu)
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
        c_inv = _stress_coefficient(J, lam, mu)
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


@njit(cache=True)
def _tangent_modes(U, s, V, J, lam, mu, values, modes, A, alpha, q):
    """The nine eigenpairs of the neo-Hookean tangent modulus ∂²W/∂F² at ``F = U diag(s) Vᵀ``.

    Writes the eigenvalues into ``values`` (9,) and the eigenvectors, as 3×3 matrices,
    into ``modes`` (9, 3, 3): the twists and flips, then the scalings (see
    :func:`scatter_bulk_hessian_projected`). ``A``, ``alpha``, ``q``: work arrays.
    """
    root_half = np.sqrt(0.5)
    psi_J = _pressure(J, lam, mu)
    m = 0
    for pair in range(3):
        i, j, k = (0, 1, 2) if pair == 0 else ((0, 2, 1) if pair == 1 else (1, 2, 0))
        for sign in (1.0, -1.0):                                 # twist, then flip
            values[m] = mu + sign * psi_J * s[k]
            for r in range(3):
                for c in range(3):
                    modes[m, r, c] = root_half * (U[r, i] * V[c, j] - sign * U[r, j] * V[c, i])
            m += 1
    for i in range(3):
        A[i, i] = _stretch_hessian_diagonal(s[i], J, lam, mu)
        for j in range(i + 1, 3):
            k = 3 - i - j
            A[i, j] = _stretch_hessian_off_diagonal(s[i], s[j], s[k], J, lam)
            A[j, i] = A[i, j]
    _jacobi_eigh3(A, alpha, q)
    for n in range(3):
        values[m] = alpha[n]
        for r in range(3):
            for c in range(3):
                modes[m, r, c] = (q[0, n] * U[r, 0] * V[c, 0] + q[1, n] * U[r, 1] * V[c, 1]
                                  + q[2, n] * U[r, 2] * V[c, 2])
        m += 1


@njit(cache=True)
def scatter_bulk_hessian_projected(data, positions, x, tets, shape_gradients, volume, lam, mu, clamp=True):
    r"""Add the bulk Hessian of every tet, with its tangent modulus projected to PSD, into ``data``.

    Same arguments as :func:`scatter_bulk_hessian`. With ``clamp=False`` the
    modes are summed with their signed eigenvalues, which rebuilds the exact
    Hessian (the test of the eigensystem below).

    Notes
    -----
    The element Hessian is ``|τ| Bᵀ C B`` with ``C = ∂²W/∂F²`` (9×9) and ``B`` the
    map ``x_e ↦ vec F`` (9×12, rank 9), so it is PSD exactly when ``C`` is; ``C``
    is projected (Teran et al. 2005). With ``F = U Σ Vᵀ`` (``U``, ``V`` rotations)
    and ``Ψ_J = ∂W/∂J = λ(J−1) − μ/J``, ``C`` has the eigenpairs (Smith, de Goes
    and Kim 2019) of

    - the twists ``(u_i v_jᵀ − u_j v_iᵀ)/√2``: ``μ + Ψ_J σ_k``;
    - the flips ``(u_i v_jᵀ + u_j v_iᵀ)/√2``: ``μ − Ψ_J σ_k``, for each pair
      ``i < j`` and ``k`` the third index;
    - the scalings ``Σ_i q_i u_i v_iᵀ``, ``q`` an eigenvector of the Hessian of
      ``ψ(σ) = W(diag σ)``: ``A_ii = μ + μ/σ_i² + λ(J/σ_i)²``,
      ``A_ij = λJ²/(σ_iσ_j) + λ(J−1)σ_k``.

    Negative eigenvalues are set to zero and the element block is
    ``|τ| Σ_m max(α_m, 0) w_m w_mᵀ``, ``(w_m)_{ai} = (D_m ∇N_a)_i``. A tet whose
    modes are all non-negative gets its exact block (to round-off).
    """
    F = np.empty((3, 3))
    U = np.empty((3, 3))
    V = np.empty((3, 3))
    s = np.empty(3)
    A = np.empty((3, 3))
    q = np.empty((3, 3))
    alpha = np.empty(3)
    modes = np.empty((9, 3, 3))
    values = np.empty(9)
    weights = np.empty(9)
    w = np.empty((9, 12))
    work = np.empty((4, 3, 3))
    for e in range(tets.shape[0]):
        G = shape_gradients[e]
        _deformation_gradient(F, x, tets[e], G)
        J = _det(F)
        _svd3(F, U, s, V, work)
        _tangent_modes(U, s, V, J, lam, mu, values, modes, A, alpha, q)
        kept = 0                                                     # modes with a non-zero weight
        for m in range(9):
            if values[m] == 0.0 or (clamp and values[m] < 0.0):
                continue
            for a in range(4):
                for i in range(3):
                    w[kept, 3 * a + i] = (modes[m, i, 0] * G[a, 0] + modes[m, i, 1] * G[a, 1]
                                          + modes[m, i, 2] * G[a, 2])
            weights[kept] = volume[e] * values[m]
            kept += 1
        for r in range(12):
            for c in range(r, 12):
                h = 0.0
                for m in range(kept):
                    h += weights[m] * w[m, r] * w[m, c]
                p = positions[e, r, c]
                if p >= 0:
                    data[p] += h
                if c != r:
                    p = positions[e, c, r]
                    if p >= 0:
                        data[p] += h


@njit(cache=True)
def _jacobi_eigh3(a, w, Q):
    """Eigenvalues ``w`` and orthonormal eigenvectors (columns of ``Q``) of a symmetric 3×3 ``a``.

    ``a`` is diagonalised in place (overwritten).

    Cyclic Jacobi rotations (Golub and Van Loan, §8.5) until the off-diagonal part is
    below round-off of the diagonal; converges quadratically, in 4-6 sweeps.
    """
    for i in range(3):
        for j in range(3):
            Q[i, j] = 1.0 if i == j else 0.0
    for _ in range(50):
        off = a[0, 1] ** 2 + a[0, 2] ** 2 + a[1, 2] ** 2
        if off <= 1e-32 * (a[0, 0] ** 2 + a[1, 1] ** 2 + a[2, 2] ** 2) or off == 0.0:
            break
        for pair in range(3):
            p, r = (0, 1) if pair == 0 else ((0, 2) if pair == 1 else (1, 2))
            if a[p, r] == 0.0:
                continue
            theta = (a[r, r] - a[p, p]) / (2.0 * a[p, r])
            t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
            c = 1.0 / np.sqrt(t * t + 1.0)
            sn = t * c
            for k in range(3):                                       # a ← a G (columns p, r)
                akp, akr = a[k, p], a[k, r]
                a[k, p] = c * akp - sn * akr
                a[k, r] = sn * akp + c * akr
            for k in range(3):                                       # a ← Gᵀ a (rows p, r)
                apk, ark = a[p, k], a[r, k]
                a[p, k] = c * apk - sn * ark
                a[r, k] = sn * apk + c * ark
            a[p, r] = 0.0                                            # zero by the choice of t
            a[r, p] = 0.0
            for k in range(3):
                qkp, qkr = Q[k, p], Q[k, r]
                Q[k, p] = c * qkp - sn * qkr
                Q[k, r] = sn * qkp + c * qkr
    for i in range(3):
        w[i] = a[i, i]


@njit(cache=True)
def _svd3(F, U, s, V, work):
    """``F = U diag(s) Vᵀ`` with ``U``, ``V`` rotations and ``s`` descending (``s[2] < 0`` iff det F < 0).

    ``V`` and ``s²`` come from ``FᵀF``; ``u_0``, ``u_1`` from ``F v_i`` (Gram-Schmidt), and
    ``u_2 = u_0 × u_1``, so that a nearly flat tet (``s_2`` ≪ ``s_0``) keeps an
    orthonormal ``U``. ``work`` is scratch space ``(4, 3, 3)``. ``F`` must have rank ≥ 2
    (every admissible tet has ``det F > 0``: the solver only assembles there).
    """
    M, Q, Fv, lam2 = work[0], work[1], work[2], work[3, 0]
    for i in range(3):
        for j in range(3):
            M[i, j] = F[0, i] * F[0, j] + F[1, i] * F[1, j] + F[2, i] * F[2, j]
    _jacobi_eigh3(M, lam2, Q)
    first, middle, last = 0, 1, 2                                    # indices of s² in descending order
    if lam2[first] < lam2[middle]:
        first, middle = middle, first
    if lam2[middle] < lam2[last]:
        middle, last = last, middle
    if lam2[first] < lam2[middle]:
        first, middle = middle, first
    for i in range(3):
        V[i, 0] = Q[i, first]
        V[i, 1] = Q[i, middle]
        V[i, 2] = Q[i, last]
    if _det(V) < 0.0:
        for i in range(3):
            V[i, 2] = -V[i, 2]
    # column j of Fv: F v_j
    for j in range(3):
        for i in range(3):
            Fv[i, j] = F[i, 0] * V[0, j] + F[i, 1] * V[1, j] + F[i, 2] * V[2, j]
    n0 = np.sqrt(Fv[0, 0] ** 2 + Fv[1, 0] ** 2 + Fv[2, 0] ** 2)
    for i in range(3):
        U[i, 0] = Fv[i, 0] / n0
    d = U[0, 0] * Fv[0, 1] + U[1, 0] * Fv[1, 1] + U[2, 0] * Fv[2, 1]
    for i in range(3):
        U[i, 1] = Fv[i, 1] - d * U[i, 0]
    n1 = np.sqrt(U[0, 1] ** 2 + U[1, 1] ** 2 + U[2, 1] ** 2)
    for i in range(3):
        U[i, 1] /= n1
    U[0, 2] = U[1, 0] * U[2, 1] - U[2, 0] * U[1, 1]
    U[1, 2] = U[2, 0] * U[0, 1] - U[0, 0] * U[2, 1]
    U[2, 2] = U[0, 0] * U[1, 1] - U[1, 0] * U[0, 1]
    for j in range(3):
        s[j] = U[0, j] * Fv[0, j] + U[1, j] * Fv[1, j] + U[2, j] * Fv[2, j]
