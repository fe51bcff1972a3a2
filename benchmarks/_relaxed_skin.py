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
"""

from __future__ import annotations

import copy

import numpy as np

from breastcore.fem import kernels
from breastcore.fem.compiled import scatter_blocks
from breastcore.fem.element_ops import _edges_to_nodes, project_psd
from breastcore.fem.skin import SkinMembrane
from breastcore.forward.model import ForwardModel

def natural_width(a, lam, mu):
    """``n(a)``, the squared transverse stretch at which a strip stretched by ``a > 1`` is free of
    transverse stress (``∂W/∂b = 0``); ``(n,)`` for ``(n,)`` ``a``.

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


def skin_states(I1, q, lam, mu):
    """``0`` slack, ``1`` wrinkled, ``2`` taut, per triangle, and the principal ``a ≥ b``, natural width ``n``."""
    s = np.sqrt(np.maximum(I1 * I1 - 4 * q, 0.0))
    a, b = 0.5 * (I1 + s), 0.5 * (I1 - s)
    n = np.ones_like(a)
    stretched = a > 1
    n[stretched] = natural_width(a[stretched], lam, mu)
    state = np.where(a <= 1, 0, np.where(b < n, 1, 2))
    return state, a, b, n


def relaxed_membrane(I1, D, det_G, lam, mu):
    """The relaxed energy per reference area and its invariant derivatives.

    Returns ``W, W_I, W_D, W_II, W_ID, W_DD``, each ``(n,)`` (J m⁻², and per unit of ``I₁`` and
    ``D = det g``), and the states of :func:`skin_states`.
    """
    q = D / det_G
    state, a, b, n = skin_states(I1, q, lam, mu)
    W, W_D, W_DD = kernels.membrane_neo_hookean(I1, D, det_G, lam, mu)
    W_I, W_II, W_ID = np.full_like(W, 0.5 * mu), np.zeros_like(W), np.zeros_like(W)
    slack, wrinkled = state == 0, state == 1
    for array in (W, W_I, W_D, W_II, W_ID, W_DD):
        array[slack] = 0.0
    if np.any(wrinkled):
        aw, nw, Iw, qw = a[wrinkled], n[wrinkled], I1[wrinkled], q[wrinkled]
        s = np.sqrt(np.maximum(Iw * Iw - 4 * qw, 0.0))
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
    (numpy, no compiled loops: a study, not the product)."""

    @classmethod
    def relaxing(cls, skin: SkinMembrane) -> "RelaxedSkinMembrane":
        """The relaxed term on ``skin``'s triangles, moduli and reference metrics."""
        term = copy.copy(skin)
        term.__class__ = cls
        return term

    def _invariant_derivatives(self, x):
        e, g, D, I1 = self._edges(x)
        derivatives, _ = relaxed_membrane(I1, D, self.det_G, self.lam, self.mu)
        dD = 2.0 * np.stack([g[:, 1, 1, None] * e[:, 0] - g[:, 0, 1, None] * e[:, 1],
                             g[:, 0, 0, None] * e[:, 1] - g[:, 0, 1, None] * e[:, 0]], axis=1)
        dI = 2.0 * np.einsum("nab,nbi->nai", self.G_inv, e)
        return e, g, derivatives, dI, dD

    def states(self, x):
        """Per triangle: 0 slack, 1 wrinkled, 2 taut (:func:`skin_states`)."""
        _, _, D, I1 = self._edges(x)
        return skin_states(I1, D / self.det_G, self.lam, self.mu)[0]

    def value(self, x):
        _, _, D, I1 = self._edges(x)
        if not np.all(D / self.det_G > 1e-12):
            return np.inf
        return float(np.sum(self.area * relaxed_membrane(I1, D, self.det_G, self.lam, self.mu)[0][0]))

    checked_value = value

    def element_gradients(self, x):
        _, _, (_, W_I, W_D, *_), dI, dD = self._invariant_derivatives(x)
        dW = W_I[:, None, None] * dI + W_D[:, None, None] * dD
        return _edges_to_nodes(dW * self.area[:, None, None], 1)

    def gradient(self, x):
        out = np.zeros(np.shape(x))
        np.add.at(out, self.connectivity, self.element_gradients(x))
        return out

    def element_hessians(self, x):
        e, g, (_, W_I, W_D, W_II, W_ID, W_DD), dI, dD = self._invariant_derivatives(x)
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
        return _edges_to_nodes(_edges_to_nodes(H, 1), 3).reshape(n, 9, 9)

    def scatter_hessian(self, data, positions, x):
        scatter_blocks(data, positions, np.ascontiguousarray(self.element_hessians(x)))

    def projected_element_hessians(self, x):
        return project_psd(self.element_hessians(x))

    def scatter_projected_hessian(self, data, positions, x):
        scatter_blocks(data, positions, np.ascontiguousarray(self.projected_element_hessians(x)))


class RelaxedSkinModel(ForwardModel):
    """A :class:`~breastcore.forward.model.ForwardModel` whose skin is a :class:`RelaxedSkinMembrane`."""

    def energy_terms(self, params, acceleration, smoothing):
        bulk, skin, gravity, sliding = super().energy_terms(params, acceleration, smoothing)
        return bulk, RelaxedSkinMembrane.relaxing(skin), gravity, sliding
