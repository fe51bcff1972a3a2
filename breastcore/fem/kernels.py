"""Pointwise constitutive kernels, vectorised over elements.

Kept apart from assembly: each function takes per-element kinematic quantities
and returns per-element scalars. Shapes use ``n`` for the number of elements.
"""

from __future__ import annotations

import numpy as np

from breastcore.fem import material


def bulk_neo_hookean(J, trace_C, lam, mu):
    r"""Compressible neo-Hookean energy density of the breast bulk and its coefficients.

    Parameters
    ----------
    J : (n,) array
        ``det F`` (must be > 0).
    trace_C : (n,) array
        ``tr(F Fᵀ)``.
    lam, mu : float
        Lamé parameters λ, μ in Pa.

    Returns
    -------
    W : (n,) array
        Energy density in J m⁻³.
    c_inv : (n,) array
        Coefficient of ``F⁻ᵀ`` in the first Piola stress.
    c_swap, c_vol : (n,) arrays
        Coefficients of the two ``F⁻¹ ⊗ F⁻¹`` terms of the tangent modulus.

    Notes
    -----
    .. math::

        W = \frac{\mu}{2}(\operatorname{tr} FF^T - 3 - 2\ln J) + \frac{\lambda}{2}(J-1)^2

        P = \mu F + c_{inv} F^{-T}, \quad c_{inv} = \lambda J (J-1) - \mu

        \frac{\partial P_{ij}}{\partial F_{kl}} = \mu\,\delta_{ik}\delta_{jl}
            + c_{swap}\, F^{-1}_{li} F^{-1}_{jk} + c_{vol}\, F^{-1}_{ji} F^{-1}_{lk}

    with ``c_swap = μ − λJ(J−1)`` and ``c_vol = λJ(2J−1)``.
    """
    c_swap, c_vol = material.tangent_coefficients(J, lam, mu)
    return material.energy_density(J, trace_C, lam, mu), material.stress_coefficient(J, lam, mu), c_swap, c_vol


def membrane_neo_hookean(I1, D, det_G, lam, mu):
    r"""Neo-Hookean membrane energy density of the skin, written with edge metrics.

    Parameters
    ----------
    I1 : (n,) array
        ``tr(G⁻¹ g) = tr(A Aᵀ)``, with ``G``, ``g`` the reference and deformed
        Gram matrices of two triangle edges.
    D : (n,) array
        ``det g`` (> 0 for a non-degenerate triangle).
    det_G : (n,) array
        ``det G``.
    lam, mu : float
        Membrane Lamé parameters times the skin thickness, in N m⁻¹.

    Returns
    -------
    W : (n,) array
        Energy per reference area, J m⁻².
    W_D, W_DD : (n,) arrays
        First and second derivatives of ``W`` with respect to ``D`` at fixed ``I1``
        (``∂W/∂I1 = μ/2`` is constant).

    Notes
    -----
    With ``det A = j = \sqrt{D / \det G}``:

    .. math::

        W = \frac{\mu}{2}(I_1 - 2 - \ln(D/\det G)) + \frac{\lambda}{2}(j - 1)^2

        W_D = -\frac{\mu}{2D} + \frac{\lambda j (j-1)}{2D}, \qquad
        W_{DD} = \frac{\mu}{2D^2} + \frac{\lambda j}{4 D^2}

    The form is invariant under rigid motions of the deformed triangle, and equals
    the paper's in-plane 2×2 Jacobian form.
    """
    ratio = D / det_G
    j = np.sqrt(ratio)
    W = 0.5 * mu * (I1 - 2.0 - np.log(ratio)) + 0.5 * lam * (j - 1.0) ** 2
    W_D = (-0.5 * mu + 0.5 * lam * j * (j - 1.0)) / D
    W_DD = (0.5 * mu + 0.25 * lam * j) / D**2
    return W, W_D, W_DD


def smoothed_norm(u, delta):
    r"""Smoothed norm ``s(u) = sqrt(|u|² + δ²) − δ`` and its derivative factors.

    Parameters
    ----------
    u : (n, 3) array
        Tangential slips of the back nodes, m.
    delta : float
        Smoothing length δ > 0, m.

    Returns
    -------
    value : (n,) array
        ``s(u)``, computed as ``|u|² / (sqrt(|u|²+δ²) + δ)`` to avoid cancellation.
    root : (n,) array
        ``r = sqrt(|u|² + δ²)``: the gradient is ``u / r`` and the Hessian is
        ``I / r − u uᵀ / r³``.
    """
    squared = np.einsum("ni,ni->n", u, u)
    root = np.sqrt(squared + delta * delta)
    return squared / (root + delta), root
