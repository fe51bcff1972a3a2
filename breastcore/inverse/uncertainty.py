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

An interval that spans more than :data:`DETERMINED_FACTOR` (``high/low = exp(2 · 1.96 σ_j)``)
says that the measurements do not determine that parameter: its bounds are NaN (never the
overflowed ``[0, inf]`` or an interval from 4e-5 to 2e11 Pa) and its width is reported in
decades, ``2 · 1.96 σ_j / ln 10``, which never overflows (it is inf only for a parameter that
the measurements do not move at all).

A parameter whose weighted relative-Jacobian column has a 2-norm below
:data:`UNSEEN_SENSITIVITY`, ``‖√W J_j‖ < 1e-6``, is *unseen*: a change by a factor e moves the
measurements by less than 1e-6 relative, far below any tape's precision, and its estimate is
wherever the optimiser stopped. A modulus sent towards 0 (or ∞) has such a column, because the
measurements tend to the limit model's as ``∂ ln M/∂ ln Λ_j → 0``; such an estimate (1.95e-27 Pa, say)
is a limit, not a value, and :func:`limits` says which way it went from its start.
"""

from __future__ import annotations

import numpy as np

Z95 = 1.959963984540054
#: A 95 % interval wider than this factor (high / low) marks its parameter as not determined.
DETERMINED_FACTOR = 10.0
#: What an undetermined parameter is called in logs and ``show``, before the parameters' names.
UNDETERMINED = f"not determined by these measurements (95 % interval wider than a factor {DETERMINED_FACTOR:g})"
#: A parameter whose weighted relative-Jacobian column is shorter than this (2-norm) is unseen.
UNSEEN_SENSITIVITY = 1e-6
#: What unseen parameters are called in logs and ``show``, before their names and limits.
_THRESHOLD = f"{UNSEEN_SENSITIVITY:.0e}".replace("e-0", "e-")                       # 1e-6, not 1e-06
UNSEEN = f"unseen by the measurements (a factor e in it moves them by less than {_THRESHOLD} relative), so not a value"
#: How far (a factor) an unseen estimate must lie from its start for :func:`limits` to give it a direction.
LIMIT_FACTOR = 10.0
#: The codes of :func:`limits`: a value (seen), a limit towards 0 or ∞, unseen without a clear direction.
SEEN, TOWARDS_ZERO, TOWARDS_INFINITY, UNSEEN_UNMOVED = 0, -1, 1, 2


def undetermined(parameters, determined_flags) -> list:
    """The names of ``parameters`` whose ``determined`` flag (an identification's variable) is 0."""
    return [str(p) for p, ok in zip(parameters, determined_flags) if not ok]


def limits(J, estimate, initial, weights=None):
    r"""Per parameter, whether its estimate is a limit (int8 array of :data:`SEEN`, :data:`TOWARDS_ZERO`,
    :data:`TOWARDS_INFINITY` or :data:`UNSEEN_UNMOVED`).

    Parameters
    ----------
    J : array, shape (n, p)
        Relative Jacobian ``∂ ln M/∂ ln Λ`` at the estimate (dimensionless).
    estimate, initial : arrays, shape (p,)
        The estimate and the optimiser's start (each parameter in its own unit, both positive).
    weights : array, shape (n,), optional
        The measurements' weights ``w_i`` (default 1).

    Notes
    -----
    Unseen: :math:`\|\sqrt{W} J_{:,j}\|_2 <` :data:`UNSEEN_SENSITIVITY`. Its direction is the sign
    of :math:`\ln(\hat\Lambda_j / \Lambda^0_j)` where the estimate lies more than :data:`LIMIT_FACTOR`
    from its start; nearer (a start already unseen, a drift at round-off) it has none
    (:data:`UNSEEN_UNMOVED`): the optimiser did not go anywhere.
    """
    J = np.asarray(J, float)
    w = np.ones(J.shape[0]) if weights is None else np.asarray(weights, float).ravel()
    unseen = np.linalg.norm(np.sqrt(w)[:, None] * J, axis=0) < UNSEEN_SENSITIVITY
    log_move = np.log(np.asarray(estimate, float) / np.asarray(initial, float))
    moved = np.where(np.abs(log_move) > np.log(LIMIT_FACTOR), np.sign(log_move), 0.0)
    direction = np.where(moved < 0, TOWARDS_ZERO, np.where(moved > 0, TOWARDS_INFINITY, UNSEEN_UNMOVED))
    return np.where(unseen, direction, SEEN).astype(np.int8)


def limit_note(limit, estimate, unit) -> str:
    """Why an unseen parameter (:func:`limits` code ``limit``, not :data:`SEEN`) has no value: one phrase."""
    where = f"{estimate:.3g} {unit} is where the optimiser stopped"
    unseen = f"a factor e in it moves the measurements by less than {_THRESHOLD} relative"
    if limit == UNSEEN_UNMOVED:
        return f"unseen, not a value ({where}, near its start; {unseen})"
    end = "0" if limit == TOWARDS_ZERO else "∞"
    return f"→ {end}, a limit, not a value ({where}; {unseen})"


def at_limit(parameters, limit_codes) -> list:
    """``"name → 0"`` (or ``→ ∞``, or ``unseen``) for each parameter whose :func:`limits` code is not SEEN."""
    ends = {TOWARDS_ZERO: " → 0", TOWARDS_INFINITY: " → ∞", UNSEEN_UNMOVED: " unseen"}
    return [f"{p}{ends[int(code)]}" for p, code in zip(parameters, limit_codes) if int(code) != SEEN]


def linearised_sensitivity(J, weights=None):
    """``S = (JᵀWJ)⁻¹ JᵀW``, shape ``(6, n)``; pseudo-inverse if rank-deficient."""
    J = np.asarray(J, float)
    w = np.ones(J.shape[0]) if weights is None else np.asarray(weights, float).ravel()
    sw = np.sqrt(w)
    return np.linalg.pinv(sw[:, None] * J) * sw[None, :]


def log_covariance(J, noise=0.10, weights=None):
    """Covariance of ``ln Λ̂`` (6×6) under relative measurement noise ``noise`` (1σ).

    A parameter along a direction that the weighted Jacobian does not see at all (a zero
    singular value, to round-off) has an infinite variance: the pseudo-inverse alone would
    give it none, an interval of zero width for a parameter the data cannot fix.
    """
    J = np.asarray(J, float)
    S = linearised_sensitivity(J, weights)
    cov = noise**2 * S @ S.T
    w = np.ones(J.shape[0]) if weights is None else np.asarray(weights, float).ravel()
    _, s, Vt = np.linalg.svd(np.sqrt(w)[:, None] * J)
    s = np.concatenate([s, np.zeros(J.shape[1] - s.size)])
    null = s <= (s[0] if s.size else 0.0) * max(J.shape) * np.finfo(float).eps
    blind = np.any(np.abs(Vt[null]) > np.sqrt(np.finfo(float).eps), axis=0) if null.any() else np.zeros(J.shape[1], bool)
    cov[blind, blind] = np.inf
    return cov


def interval_decades(cov_log, z=Z95):
    """Width ``log10(high/low) = 2 z σ_j / ln 10`` of each (default 95 %) interval, in decades."""
    sigma = np.sqrt(np.clip(np.diag(np.asarray(cov_log, float)), 0.0, None))
    return 2.0 * z * sigma / np.log(10.0)


def determined(cov_log, z=Z95, max_factor=DETERMINED_FACTOR):
    """Whether each parameter's interval spans at most ``max_factor`` (bool array)."""
    return interval_decades(cov_log, z) <= np.log10(max_factor)


def intervals(values, cov_log, z=Z95, max_factor=DETERMINED_FACTOR):
    """Bounds ``Λ exp(∓ z σ)`` of the (default 95 %) interval; NaN for a parameter that is not
    :func:`determined` (its width is tested in log space first, so nothing overflows)."""
    sigma = np.sqrt(np.clip(np.diag(np.asarray(cov_log, float)), 0.0, None))
    values = np.asarray(values, float)
    ok = determined(cov_log, z, max_factor)
    spread = np.exp(np.where(ok, z * sigma, 0.0))
    return np.where(ok, values / spread, np.nan), np.where(ok, values * spread, np.nan)


def conditioning(J):
    """Singular values of ``J`` (descending), its numerical rank and condition number."""
    s = np.linalg.svd(np.asarray(J, float), compute_uv=False)
    rank = int(np.sum(s > s[0] * max(J.shape) * np.finfo(float).eps))
    return s, rank, float(s[0] / s[-1]) if s[-1] > 0 else np.inf
