r"""The compressible neo-Hookean law of the breast bulk, written once.

Every function is plain arithmetic on floats or numpy arrays, so that the same code
serves the vectorised numpy kernels (:func:`breastcore.fem.kernels.bulk_neo_hookean`,
the test oracle) and, compiled by numba, the element loops of
:mod:`breastcore.fem.compiled`. ``tests/fem/test_material.py`` checks its derivatives
against finite differences.

Notes
-----
With ``J = det F``, ``C = Fᵀ F``:

.. math::

    W = \frac{\mu}{2}(\operatorname{tr} C - 3 - 2\ln J) + \frac{\lambda}{2}(J-1)^2,
    \qquad P = \mu F + c_{inv} F^{-T}, \quad c_{inv} = \lambda J (J-1) - \mu,

    \frac{\partial P_{ij}}{\partial F_{kl}} = \mu\,\delta_{ik}\delta_{jl}
        + c_{swap}\, F^{-1}_{li} F^{-1}_{jk} + c_{vol}\, F^{-1}_{ji} F^{-1}_{lk},
    \qquad c_{swap} = \mu - \lambda J(J-1), \quad c_{vol} = \lambda J(2J-1).

In principal stretches ``σ``: ``ψ_J = λ(J−1) − μ/J``, and the Hessian of
``ψ(σ) = W(diag σ)`` has ``A_ii = μ + μ/σ_i² + λ(J/σ_i)²`` and
``A_ij = λJ²/(σ_iσ_j) + λ(J−1)σ_k`` (``k`` the third index).
"""

from __future__ import annotations

import numpy as np


def energy_density(J, trace_C, lam, mu):
    """W in J m⁻³ (Pa), from ``J = det F`` (> 0) and ``tr C``."""
    return 0.5 * mu * (trace_C - 3.0 - 2.0 * np.log(J)) + 0.5 * lam * (J - 1.0) ** 2


def stress_coefficient(J, lam, mu):
    """``c_inv``, the coefficient of ``F⁻ᵀ`` in the first Piola stress ``P = μF + c_inv F⁻ᵀ``, Pa."""
    return lam * J * (J - 1.0) - mu


def tangent_coefficients(J, lam, mu, scale=1.0):
    """``(scale · c_swap, scale · c_vol)``, Pa (times ``scale``: a tet's volume in the loops)."""
    return scale * (mu - lam * J * (J - 1.0)), scale * lam * J * (2.0 * J - 1.0)


def pressure(J, lam, mu):
    """``ψ_J = λ(J−1) − μ/J``, the J-derivative of W's volumetric part ``λ/2 (J−1)² − μ ln J``, Pa.

    The twist and flip eigenvalues of the tangent modulus are ``μ ± ψ_J σ_k``.
    """
    return lam * (J - 1.0) - mu / J


def stretch_hessian_diagonal(s_i, J, lam, mu):
    """``A_ii = ∂²ψ/∂σ_i²`` of ``ψ(σ) = W(diag σ)``, Pa."""
    return mu + mu / (s_i * s_i) + lam * (J / s_i) ** 2


def stretch_hessian_off_diagonal(s_i, s_j, s_k, J, lam):
    """``A_ij = ∂²ψ/∂σ_i∂σ_j`` (``k`` the third index), Pa."""
    return lam * J * J / (s_i * s_j) + lam * (J - 1.0) * s_k


def first_piola(F, lam, mu):
    """``P(F)``, ``(..., 3, 3)`` Pa, for deformation gradients ``F`` of shape ``(..., 3, 3)``."""
    J = np.linalg.det(F)
    return mu * F + stress_coefficient(J, lam, mu)[..., None, None] * np.swapaxes(np.linalg.inv(F), -1, -2)


def tangent_modulus(F, lam, mu):
    """``∂P_ij/∂F_kl``, ``(..., 3, 3, 3, 3)`` Pa."""
    J = np.linalg.det(F)
    c_swap, c_vol = tangent_coefficients(J, lam, mu)
    Finv = np.linalg.inv(F)
    eye = np.eye(3)
    return (mu * np.einsum("ik,jl->ijkl", eye, eye)
            + c_swap[..., None, None, None, None] * np.einsum("...li,...jk->...ijkl", Finv, Finv)
            + c_vol[..., None, None, None, None] * np.einsum("...ji,...lk->...ijkl", Finv, Finv))
