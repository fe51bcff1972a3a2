r"""Linearised uncertainty and sensitivity of an identified Λ.

All matrices use the relative Jacobian ``J = ∂ ln M / ∂ ln Λ`` (measurements × 6).

Notes
-----
Noise model: each measurement carries independent relative noise,
``M̄_i = M_i (1 + ε_i)``, ``ε_i ~ N(0, σ²)`` (default σ = 0.10, 1σ). Linearising the
weighted least-squares estimator ``ln Λ̂ = ln Λ + S ε`` with
``S = (JᵀWJ)⁻¹ JᵀW`` gives

.. math:: \operatorname{Cov}(\ln \hat\Lambda) = \sigma^2 S S^T

and the 95 % interval ``Λ̂ exp(±1.96 σ_j)``. ``S`` is also the paper's relative
sensitivity matrix ``∂ ln Λ_j / ∂ ln m_i`` in its linearised form.
"""

from __future__ import annotations

import numpy as np

Z95 = 1.959963984540054


def linearised_sensitivity(J, weights=None):
    """``S = (JᵀWJ)⁻¹ JᵀW``, shape ``(6, n)``; pseudo-inverse if rank-deficient."""
    J = np.asarray(J, float)
    w = np.ones(J.shape[0]) if weights is None else np.asarray(weights, float).ravel()
    sw = np.sqrt(w)
    return np.linalg.pinv(sw[:, None] * J) * sw[None, :]


def log_covariance(J, noise=0.10, weights=None):
    """Covariance of ``ln Λ̂`` (6×6) under relative measurement noise ``noise`` (1σ)."""
    S = linearised_sensitivity(J, weights)
    return noise**2 * S @ S.T


def intervals(values, cov_log, z=Z95):
    """Lower and upper bounds ``Λ exp(∓ z σ)`` of the (default 95 %) interval."""
    sigma = np.sqrt(np.clip(np.diag(cov_log), 0.0, None))
    values = np.asarray(values, float)
    return values * np.exp(-z * sigma), values * np.exp(z * sigma)


def conditioning(J):
    """Singular values of ``J`` (descending), its numerical rank and condition number."""
    s = np.linalg.svd(np.asarray(J, float), compute_uv=False)
    rank = int(np.sum(s > s[0] * max(J.shape) * np.finfo(float).eps))
    return s, rank, float(s[0] / s[-1]) if s[-1] > 0 else np.inf
