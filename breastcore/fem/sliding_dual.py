"""The dual variable of the Chassaignac term, for primal-dual Newton steps (issue #21).

Newton's method on the smoothed sliding energy ``Σ_n w_n (sqrt(|u_n|²+δ²) − δ)`` converges
slowly when a back node changes between sticking (``|u| ≲ δ``) and slipping: the force
``u/r`` saturates within δ = 1e-6 m, so its linearisation at a sticking node predicts
δ-sized moves. Chan, Golub and Mulet (1999) keep the force direction as a separate
unknown ``q = u/r``, ``|q| ≤ 1``, and linearise ``r q − u = 0`` instead, which has no
such saturation. Eliminating ``q`` node by node leaves a primal step with another
sliding block; :class:`SlidingDual` holds ``q`` between Newton iterations and gives those
blocks. The energy, its gradient and the converged state are unchanged: only the step
matrix differs, and it equals the exact Hessian once ``q = u/r``.
"""

from __future__ import annotations

import numpy as np


class SlidingDual:
    r"""Dual state ``q`` of a :class:`~breastcore.fem.loads.Chassaignac` term and its step blocks.

    Parameters
    ----------
    term : Chassaignac
        The sliding term (its ``connectivity``, ``anchor``, ``weight`` and ``smoothing``).

    Notes
    -----
    At node positions with slips :math:`u` (m), :math:`r = \sqrt{|u|^2+\delta^2}`, the
    Newton system of the pair :math:`(x, q)` with the equations
    :math:`\nabla_x J_{\text{rest}} + w q = 0` and :math:`r q - u = 0` gives, after
    eliminating :math:`\Delta q`, the sliding block (N m⁻¹)

    .. math:: B = \frac{w}{r}\Big(I - \frac{q u^\top + u q^\top}{2r}\Big)

    (symmetrised; positive definite for :math:`|q| \le 1`, since
    :math:`|u| < r`) and the primal gradient as right-hand side. After a step to slips
    :math:`u' = u + \Delta u`, the linearised dual update is

    .. math:: q' = \Big(u' - q\,\frac{u\cdot\Delta u}{r}\Big)\Big/ r,

    scaled back to :math:`|q'| \le 1`. With :math:`q = u/r`, :math:`B` is the exact
    Hessian :math:`w (I/r - u u^\top/r^3)` and :math:`q'` is the first-order
    Taylor value of :math:`u'/r'`.
    """

    def __init__(self, term):
        self.term = term
        self.connectivity = term.connectivity
        self._slips = None       # the slips u (n, 3) at which q was last updated
        self._root = None
        self.q = None

    def update(self, x):
        """Move ``q`` to the node positions ``x`` (N, 3) by the linearised update (a no-op at the same slips)."""
        u, _, root = self.term._slip(x)                  # the term's own slips and roots
        if self.q is None:
            q = u / root[:, None]
        elif np.array_equal(u, self._slips):
            return
        else:
            u0, r0 = self._slips, self._root
            q = (u - self.q * (np.einsum("ni,ni->n", u0, u - u0) / r0)[:, None]) / r0[:, None]
        self.q = q / np.maximum(1.0, np.linalg.norm(q, axis=1))[:, None]
        self._slips, self._root = u, root

    def element_hessians(self, x):
        """``(n, 3, 3)`` step blocks ``B`` (N m⁻¹) at ``x``, after :meth:`update`."""
        self.update(x)
        u, q, r = self._slips, self.q, self._root
        sym = 0.5 * (np.einsum("ni,nj->nij", q, u) + np.einsum("ni,nj->nij", u, q)) / r[:, None, None]
        return (self.term.weight / r)[:, None, None] * (np.eye(3)[None] - sym)

    def projected_element_hessians(self, x):
        """:meth:`element_hessians`: these blocks are positive definite already."""
        return self.element_hessians(x)
