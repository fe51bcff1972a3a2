r"""A tension-field (relaxed) skin membrane, for a study of the model (``bench_relaxed_skin.py``).

**Not the spec's model.** The spec's skin (:class:`~breastcore.fem.skin.SkinMembrane`) resists
compression; a membrane has no bending stiffness, so its compressed triangles are unstable, and
on fine meshes a cold solve spends much of its time in indefinite phases that come from them
(``docs/benchmarks.md``, "How much of a cold solve is the stick-slip front?"). Here the membrane
energy is replaced by its relaxation (Pipkin 1986), in which a compressed direction wrinkles at no
energy. Only the forward solve is provided: the relaxed energy is not linear in each skin modulus
alone (the natural width depends on λ_s/μ_s), so :func:`breastcore.fem.terms.modulus_gradient`, and
with it the identification's implicit Jacobian, does not apply to it.

Notes
-----
With ``a ≥ b`` the squared principal stretches of a triangle (``a + b = I₁``, ``ab = q = det g / det G``,
``s = a − b = √(I₁² − 4q)``), the spec's membrane energy per reference area is

.. math::

    W(a, b) = \frac{\mu}{2}(a + b - 2 - \ln ab) + \frac{\lambda}{2}(\sqrt{ab} - 1)^2 .

The **natural width** ``n(a) ∈ (0, 1)`` of a strip stretched by ``a > 1`` solves ``∂W/∂b (a, n) = 0``,
i.e. with ``y = √n``: ``μ(y² − 1) + λ(a y² − √a y) = 0``. The relaxed energy is

.. math::

    \tilde W = \begin{cases} 0 & a \le 1 \text{ (slack)}\\
        W(a, n(a)) & a > 1,\ b < n(a) \text{ (wrinkled)}\\
        W(a, b) & \text{otherwise (taut)} \end{cases}

continuous with its first derivatives across the states. Wrinkled, ``W̃' = W_a`` (as ``W_b = 0``) and
``W̃'' = W_aa − W_ab² / W_bb`` at ``(a, n(a))``, and the chain to the invariants uses
``a_I = (1 + I₁/s)/2``, ``a_q = −1/s``, ``a_II = −2q/s³``, ``a_Iq = I₁/s³``, ``a_qq = −2/s³``.
Where the three states meet, ``a = b = 1`` (the gravity-free shape), the relaxed energy is not twice
differentiable and ``s → 0``. The energy and the forces are exact everywhere; the Hessian of a
triangle within :data:`TRIPLE_POINT` of that point is the taut side's (the spec's), because there
the invariant form's ``1/s³`` terms cancel into noise. Outside, every wrinkled triangle has
``s > TRIPLE_POINT``, and the invariant form loses accuracy as ``ε/s²`` (ε the machine epsilon):
on the tests' patch, wrinkled blocks are positive semidefinite to 2.2e-8 of their largest eigenvalue
at strains of 1e-4, and to 4.2e-9 at 1e-3 (``tests/test_relaxed_skin.py``).
"""

from __future__ import annotations

import copy

import numpy as np

from breastcore.fem import kernels
from breastcore.fem.compiled import scatter_blocks
from breastcore.fem.element_ops import _edges_to_nodes, project_psd
from breastcore.fem.skin import SkinMembrane
from breastcore.forward.model import ForwardModel

#: A triangle with both squared stretches within this of 1 takes the taut side's Hessian: near
#: ``a = b = 1``, where the three states meet (the gravity-free shape is there), round-off decides
#: the state and the invariant form of the wrinkled Hessian loses accuracy as ε/s² (module Notes).
TRIPLE_POINT = 1e-4


def natural_width(a, lam, mu):
    """The natural width ``n(a)``: the squared transverse stretch at which a strip stretched by ``a``
    is free of transverse stress (``∂W/∂b = 0``).

    Parameters
    ----------
    a : (n,) array
        Squared stretch along the strip, ``a ≥ 1``.
    lam, mu : float
        Membrane Lamé moduli (N m⁻¹).

    Returns
    -------
    (n,) array
        ``n(a) ∈ (0, 1]``, with ``n(1) = 1``.

    Notes
    -----
    With ``y = √n``, ``2b ∂W/∂b = μ(y² − 1) + λ(a y² − √a y) = 0``: the positive root of
    ``(μ + λa) y² − λ√a y − μ = 0``.
    """
    a = np.asarray(a, float)
    quadratic = mu + lam * a
    y = (lam * np.sqrt(a) + np.sqrt(lam * lam * a + 4 * mu * quadratic)) / (2 * quadratic)
    return y * y


def _principal_derivatives(a, b, lam, mu):
    """``W, W_a, W_b, W_aa, W_ab, W_bb`` of the membrane energy in the squared principal stretches."""
    j = np.sqrt(a * b)
    W = 0.5 * mu * (a + b - 2 - np.log(a * b)) + 0.5 * lam * (j - 1) ** 2
    W_a = 0.5 * mu * (1 - 1 / a) + 0.5 * lam * (j - 1) * j / a
    W_b = 0.5 * mu * (1 - 1 / b) + 0.5 * lam * (j - 1) * j / b
    W_aa = 0.5 * mu / a ** 2 + 0.25 * lam * j / a ** 2
    W_bb = 0.5 * mu / b ** 2 + 0.25 * lam * j / b ** 2
    W_ab = 0.5 * lam * (1 - 0.5 / j)
    return W, W_a, W_b, W_aa, W_ab, W_bb


def principal_gap(G_inv, g):
    """``s = a − b ≥ 0``, the gap between the squared principal stretches, ``(n,)``.

    The eigenvalues of ``M = G⁻¹ g`` (``(n, 2, 2)`` each) differ by ``√((M₁₁ − M₂₂)² + 4 M₁₂ M₂₁)``;
    computed so, not as ``√(I₁² − 4q)``, ``s`` keeps its relative accuracy as ``a → b`` (the latter
    turns a round-off of 1e-16 into ``s ≈ 1e-8`` at the gravity-free shape).
    """
    M = np.einsum("nab,nbc->nac", G_inv, g)
    return np.sqrt(np.maximum((M[:, 0, 0] - M[:, 1, 1]) ** 2 + 4 * M[:, 0, 1] * M[:, 1, 0], 0.0))


def skin_states(I1, s, lam, mu):
    """The state of each triangle and its principal values.

    Parameters
    ----------
    I1, s : (n,) arrays
        ``tr(G⁻¹ g) = a + b`` and :func:`principal_gap` ``a − b``.
    lam, mu : float
        Membrane Lamé moduli (N m⁻¹).

    Returns
    -------
    state : (n,) int array
        0 slack (``a ≤ 1``), 1 wrinkled (``a > 1``, ``b < n(a)``), 2 taut (otherwise).
    a, b, n : (n,) arrays
        Squared principal stretches ``a ≥ b`` and the natural width ``n(a)`` (1 where ``a ≤ 1``).
    """
    a, b = 0.5 * (I1 + s), 0.5 * (I1 - s)
    n = np.ones_like(a)
    stretched = a > 1
    n[stretched] = natural_width(a[stretched], lam, mu)
    state = np.where(a <= 1, 0, np.where(b < n, 1, 2))
    return state, a, b, n


def near_triple_point(I1, s):
    """``(n,)`` bool: both squared principal stretches within :data:`TRIPLE_POINT` of 1."""
    a, b = 0.5 * (I1 + s), 0.5 * (I1 - s)
    return (np.abs(a - 1) <= TRIPLE_POINT) & (np.abs(b - 1) <= TRIPLE_POINT)


def relaxed_membrane(I1, D, s, det_G, lam, mu):
    """The relaxed energy per reference area and its invariant derivatives.

    Parameters
    ----------
    I1, D, s, det_G : (n,) arrays
        ``tr(G⁻¹ g)``, ``det g`` (m⁴), :func:`principal_gap` and ``det G`` (m⁴) per triangle.
    lam, mu : float
        Membrane Lamé moduli (N m⁻¹).

    Returns
    -------
    derivatives : tuple of six (n,) arrays
        ``W, W_I, W_D, W_II, W_ID, W_DD``: J m⁻², and per unit of ``I₁`` and ``D``.
    state : (n,) int array
        :func:`skin_states`.
    """
    q = D / det_G
    if lam == 0 and mu == 0:                          # the skin switched off
        zero = np.zeros_like(I1)
        return (zero, zero, zero, zero, zero, zero), np.full(I1.shape, 2)
    state, a, b, n = skin_states(I1, s, lam, mu)
    W, W_D, W_DD = kernels.membrane_neo_hookean(I1, D, det_G, lam, mu)
    W_I, W_II, W_ID = np.full_like(W, 0.5 * mu), np.zeros_like(W), np.zeros_like(W)
    slack, wrinkled = state == 0, state == 1
    for array in (W, W_I, W_D, W_II, W_ID, W_DD):
        array[slack] = 0.0
    if np.any(wrinkled):
        aw, nw, Iw, qw, s = a[wrinkled], n[wrinkled], I1[wrinkled], q[wrinkled], s[wrinkled]
        Wt, Wt1, _, W_aa, W_ab, W_bb = _principal_derivatives(aw, nw, lam, mu)
        Wt2 = W_aa - W_ab ** 2 / W_bb
        a_I, a_q = 0.5 * (1 + Iw / s), -1 / s
        a_II, a_Iq, a_qq = -2 * qw / s ** 3, Iw / s ** 3, -2 / s ** 3
        dG = det_G[wrinkled]
        W[wrinkled] = Wt
        W_I[wrinkled] = Wt1 * a_I
        W_D[wrinkled] = Wt1 * a_q / dG
        W_II[wrinkled] = Wt2 * a_I ** 2 + Wt1 * a_II
        W_ID[wrinkled] = (Wt2 * a_I * a_q + Wt1 * a_Iq) / dG
        W_DD[wrinkled] = (Wt2 * a_q ** 2 + Wt1 * a_qq) / dG ** 2
    return (W, W_I, W_D, W_II, W_ID, W_DD), state


class RelaxedSkinMembrane(SkinMembrane):
    """:class:`~breastcore.fem.skin.SkinMembrane` with the relaxed energy :func:`relaxed_membrane`
    (numpy, no compiled loops: a study, not the product). Arrays and units as the parent's.

    Its forces refuse one zero modulus (both zero, the skin switched off, give zero):
    :func:`breastcore.fem.terms.modulus_gradient` (the implicit Jacobian's derivative in a skin
    modulus) zeroes one, which is valid only for an energy linear in each modulus, and would
    otherwise give a wrong Jacobian without a word. So λ_s = 0 with μ_s > 0 (or the reverse), which
    the spec allows, is not supported by this study.
    """

    @classmethod
    def relaxing(cls, skin: SkinMembrane) -> "RelaxedSkinMembrane":
        """The relaxed term on ``skin``'s triangles, moduli and reference metrics."""
        term = copy.copy(skin)
        term.__class__ = cls
        return term

    def _kinematics(self, x):
        """Edges ``(S, 2, 3)``, Gram matrices ``(S, 2, 2)``, ``D``, ``I₁`` and :func:`principal_gap`."""
        e, g, D, I1 = self._edges(x)
        return e, g, D, I1, principal_gap(self.G_inv, g)

    def _invariant_derivatives(self, x):
        """Edges, Gram matrices, :func:`relaxed_membrane`'s six derivatives, ``∂I₁/∂e`` and ``∂D/∂e``
        (``(S, 2, 3)`` each), and the triangles near the triple point."""
        if (self.lam == 0) != (self.mu == 0):
            raise ValueError("the relaxed skin refuses one zero modulus: its energy is not linear in each "
                             "modulus, and modulus_gradient (which zeroes one) would be wrong without a word")
        e, g, D, I1, s = self._kinematics(x)
        derivatives, _ = relaxed_membrane(I1, D, s, self.det_G, self.lam, self.mu)
        dD = self._edge_gradient(e, g, D, I1)[1]                       # the parent's ∂D/∂e
        dI = 2.0 * np.einsum("nab,nbi->nai", self.G_inv, e)
        return e, g, derivatives, dI, dD, near_triple_point(I1, s)

    def states(self, x):
        """Per triangle: 0 slack, 1 wrinkled, 2 taut (:func:`skin_states`)."""
        _, _, _, I1, s = self._kinematics(x)
        return skin_states(I1, s, self.lam, self.mu)[0]

    def element_energies(self, x):
        """``|T| W̃`` per triangle ``(S,)``, J."""
        _, _, D, I1, s = self._kinematics(x)
        return self.area * relaxed_membrane(I1, D, s, self.det_G, self.lam, self.mu)[0][0]

    def value(self, x):
        """Energy in J, ``+inf`` if a triangle is degenerate (as the parent's)."""
        if not self.admissible(x):
            return np.inf
        return float(np.sum(self.element_energies(x)))

    checked_value = value

    def element_gradients(self, x):
        """Per-triangle nodal forces ``(S, 3, 3)``, N."""
        _, _, (_, W_I, W_D, *_), dI, dD, _ = self._invariant_derivatives(x)
        dW = W_I[:, None, None] * dI + W_D[:, None, None] * dD
        return _edges_to_nodes(dW * self.area[:, None, None], 1)

    def gradient(self, x):
        """Nodal forces ``(N, 3)``, N."""
        out = np.zeros(np.shape(x))
        np.add.at(out, self.connectivity, self.element_gradients(x))
        return out

    def element_hessians(self, x):
        """Per-triangle Hessian blocks ``(S, 9, 9)``, N m⁻¹:
        ``W_I ∂²I₁ + W_D ∂²D + W_II ∂I₁∂I₁ + W_ID (∂I₁∂D + ∂D∂I₁) + W_DD ∂D∂D``; the spec's blocks for
        the triangles within :data:`TRIPLE_POINT` of ``a = b = 1`` (the taut side's Hessian)."""
        e, g, (_, W_I, W_D, W_II, W_ID, W_DD), dI, dD, near = self._invariant_derivatives(x)
        n, eye = len(e), np.eye(3)
        e1, e2, e12 = e[:, 0], e[:, 1], g[:, 0, 1]
        outer = lambda u, v: np.einsum("ni,nj->nij", u, v)  # noqa: E731
        d2D = np.empty((n, 2, 3, 2, 3))
        d2D[:, 0, :, 0, :] = 2 * g[:, 1, 1, None, None] * eye - 2 * outer(e2, e2)
        d2D[:, 1, :, 1, :] = 2 * g[:, 0, 0, None, None] * eye - 2 * outer(e1, e1)
        d2D[:, 0, :, 1, :] = 4 * outer(e1, e2) - 2 * outer(e2, e1) - 2 * e12[:, None, None] * eye
        d2D[:, 1, :, 0, :] = np.swapaxes(d2D[:, 0, :, 1, :], 1, 2)
        pair = lambda u, v: np.einsum("nai,nbj->naibj", u, v)  # noqa: E731
        H = 2 * W_I[:, None, None, None, None] * np.einsum("nab,ij->naibj", self.G_inv, eye)
        H += W_D[:, None, None, None, None] * d2D
        H += W_II[:, None, None, None, None] * pair(dI, dI)
        H += W_ID[:, None, None, None, None] * (pair(dI, dD) + pair(dD, dI))
        H += W_DD[:, None, None, None, None] * pair(dD, dD)
        H *= self.area[:, None, None, None, None]
        blocks = _edges_to_nodes(_edges_to_nodes(H, 1), 3).reshape(n, 9, 9)
        if np.any(near):
            blocks[near] = SkinMembrane.element_hessians(self, x)[near]
        return blocks

    def scatter_hessian(self, data, positions, x):
        """Add :meth:`element_hessians` into CSR ``data`` at ``positions``."""
        scatter_blocks(data, positions, np.ascontiguousarray(self.element_hessians(x)))

    def projected_element_hessians(self, x):
        """:meth:`element_hessians` with each block's negative eigenvalues set to zero."""
        return project_psd(self.element_hessians(x))

    def scatter_projected_hessian(self, data, positions, x):
        """Add :meth:`projected_element_hessians` into CSR ``data`` at ``positions``."""
        scatter_blocks(data, positions, np.ascontiguousarray(self.projected_element_hessians(x)))


class RelaxedSkinModel(ForwardModel):
    """A :class:`~breastcore.forward.model.ForwardModel` whose skin is a :class:`RelaxedSkinMembrane`."""

    def energy_terms(self, params, acceleration, smoothing):
        """The parent's four terms, the skin relaxed."""
        bulk, skin, gravity, sliding = super().energy_terms(params, acceleration, smoothing)
        return bulk, RelaxedSkinMembrane.relaxing(skin), gravity, sliding
