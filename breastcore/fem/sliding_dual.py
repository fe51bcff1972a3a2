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

A sticking node that the body pulls past the threshold still moves by δ-sized steps under these
blocks; :meth:`SlidingDual.release` steps such nodes as slipping (a semismooth Newton step of the
unsmoothed law), which changes the step's right-hand side too (``SolverOptions.sliding_release``).
"""

from __future__ import annotations

import numpy as np


#: :meth:`SlidingDual.release`: a sticking node is released where its demand exceeds this (the
#: threshold is 1). With :data:`RELEASE_MAX_SLIP` = 10: the fewest factorisations of six pairs
#: (1-1.05, 3-100) over the cold solves at Λ̄ on ultra-thin, reference and fine10k, and the least
#: time of seven pairs (1.05-2, 3-10) on medium to reference (docs/benchmarks.md, "Released
#: sliding steps").
RELEASE_DEMAND = 1.05
#: :meth:`SlidingDual.release`: only nodes that slip at most this many δ are released (further out
#: the primal-dual block has lost its stiffness along the slip already).
RELEASE_MAX_SLIP = 10.0


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
    :math:`|u| < r`; a node released by :meth:`release` has the semi-definite block
    :math:`(w/r)(I - e e^\top)` instead) and the primal gradient as right-hand side. After a step to slips
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
        self._released = None    # (node positions, released mask, slip directions) of the last release()

    def release(self, x, gradient):
        """Mark the sticking back nodes that the rest of the energy pulls harder than the sliding
        threshold; return the correction of the step's right-hand side, (N, 3) N.

        Parameters
        ----------
        x : (N, 3) array
            Node positions, m.
        gradient : (N, 3) array
            The energy's gradient at ``x``, N (zero at fixed dofs).

        Returns
        -------
        (N, 3) array
            ``w (d/|d| − u/r)`` at the released nodes, zero elsewhere, N: added to the gradient,
            it makes the step's sliding force of a released node the saturated ``w d/|d|``.

        Notes
        -----
        At a back node the rest of the energy pulls with ``−g_rest = w d``, where ``d = u/r − g/w``
        is the **demand** (``g`` the whole gradient, ``w u/r`` the sliding force). Where
        ``|d| > 1`` the node slips in the unsmoothed law, but while it sticks (``|u| ≲ δ``) its
        sliding block ``w/r`` is ~10⁴ times the bulk's nodal stiffness: a Newton step moves it by a
        few δ, and the slip zone widens by about one ring of nodes per iteration (10 iterations on
        the ultra-thin standing posture). A node with ``|d| >`` :data:`RELEASE_DEMAND` and
        ``|u| ≤`` :data:`RELEASE_MAX_SLIP` δ is **released**: stepped as in a semismooth Newton
        step of the unsmoothed law, with the constant force ``w d/|d|`` and no stiffness along
        ``d`` (:meth:`element_hessians`). At an equilibrium ``|d| = |u|/r < 1``, so no node is
        released there and the last steps are the primal-dual ones. The gradient, the energy and
        the line search are unchanged.
        """
        u, _, root = self.term._slip(x)
        nodes = self.connectivity[:, 0]
        weight = self.term.weight
        with np.errstate(divide="ignore", invalid="ignore"):
            demand = u / root[:, None] - gradient[nodes] / weight[:, None]
        size = np.linalg.norm(demand, axis=1)
        released = (weight > 0) & (size > RELEASE_DEMAND) & \
            (np.linalg.norm(u, axis=1) <= RELEASE_MAX_SLIP * self.term.smoothing)
        direction = np.zeros_like(u)
        direction[released] = demand[released] / size[released, None]
        self._released = (np.array(x, dtype=float), released, direction)
        correction = np.zeros_like(x)
        correction[nodes[released]] = weight[released, None] * (direction[released] - u[released] /
                                                                 root[released, None])
        return correction

    def clear_release(self):
        """Forget the last :meth:`release`: the blocks are the primal-dual ones everywhere."""
        self._released = None

    def _released_at(self, x):
        """The released mask and directions of the last :meth:`release` if it was at positions ``x``, else None."""
        if self._released is None or not np.array_equal(self._released[0], x):
            return None
        return self._released[1:]

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
        """``(n, 3, 3)`` step blocks ``B`` (N m⁻¹) at ``x``, after :meth:`update`; at the nodes that
        :meth:`release` released at ``x``, ``(w/r)(I − e eᵀ)`` with ``e`` the unit demand (positive
        semi-definite: the bulk holds such a node along ``e``)."""
        self.update(x)
        u, q, r = self._slips, self.q, self._root
        sym = 0.5 * (np.einsum("ni,nj->nij", q, u) + np.einsum("ni,nj->nij", u, q)) / r[:, None, None]
        released = self._released_at(x)
        if released is not None and released[0].any():    # released: no stiffness along d (release())
            mask, e = released
            sym[mask] = np.einsum("ni,nj->nij", e[mask], e[mask])
        return (self.term.weight / r)[:, None, None] * (np.eye(3)[None] - sym)

    def projected_element_hessians(self, x):
        """:meth:`element_hessians`: these blocks are positive definite already (semi-definite at
        released nodes)."""
        return self.element_hessians(x)
