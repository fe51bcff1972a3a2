"""Linearised uncertainty on a synthetic linear model (issue #3).

The model is exactly linear in log space: ``ln M(Λ) = ln M(Λ*) + J (ln Λ − ln Λ*)``,
so the least-squares estimate under relative noise ``M̄ = M(Λ*)(1 + ε)`` is
``ln Λ̂ = ln Λ* + S ln(1 + ε)`` with ``S = (JᵀWJ)⁻¹JᵀW``. Monte Carlo on it checks
``log_covariance`` (to first order in ε: ln(1 + ε) ≈ ε) and the 95 % intervals.
"""

import numpy as np
import pytest

from breastcore.inverse.uncertainty import Z95, conditioning, intervals, linearised_sensitivity, log_covariance

N_MEAS, N_PAR = 15, 6
TRUTH = np.array([0.0562, 0.05, 1000.0, 150.0, 8000.0, 1600.0])


@pytest.fixture(scope="module")
def linear_model():
    rng = np.random.default_rng(20240603)
    J = rng.normal(size=(N_MEAS, N_PAR))
    J[:, 5] *= 0.2                                  # one weakly identified parameter, like μ_s
    return J


def estimate(J, noise_draws, weights=None):
    """Weighted least-squares re-solve of the linear model for each noisy draw (rows)."""
    w = np.ones(J.shape[0]) if weights is None else weights
    sw = np.sqrt(w)
    rhs = np.log1p(noise_draws) * sw                                  # ln m̄ − ln M(Λ*)
    dz, *_ = np.linalg.lstsq(sw[:, None] * J, rhs.T, rcond=None)
    return TRUTH[None, :] * np.exp(dz.T)                              # (draws, 6)


def test_log_covariance_matches_monte_carlo_and_intervals_cover_95_percent(linear_model):
    J, sigma, draws = linear_model, 0.02, 2000
    rng = np.random.default_rng(7)
    eps = sigma * rng.standard_normal((draws, N_MEAS))
    est = estimate(J, eps)
    cov = log_covariance(J, sigma)
    sample = np.cov(np.log(est / TRUTH), rowvar=False)
    # variances within sampling error: the relative s.d. of a sample variance is sqrt(2/(n−1)) ≈ 3.2 %
    assert np.allclose(np.diag(sample), np.diag(cov), rtol=4 * np.sqrt(2.0 / (draws - 1)))
    # correlations within ~4 standard errors (1/sqrt(n) ≈ 0.022)
    d = np.sqrt(np.diag(cov))
    assert np.abs(sample / np.outer(d, d) - cov / np.outer(d, d)).max() < 0.1
    # coverage of the 95 % interval around each estimate, per parameter (linear ⇒ exact in log space)
    covered = np.zeros(N_PAR)
    for row in est:
        low, high = intervals(row, cov)
        covered += (low <= TRUTH) & (TRUTH <= high)
    coverage = covered / draws
    assert np.all((0.93 <= coverage) & (coverage <= 0.97)), coverage


def test_covariance_scales_with_noise_squared(linear_model):
    assert np.allclose(log_covariance(linear_model, 0.2), 4.0 * log_covariance(linear_model, 0.1))


def test_intervals_bracket_the_estimate_and_are_symmetric_in_log_space(linear_model):
    cov = log_covariance(linear_model, 0.10)
    low, high = intervals(TRUTH, cov)
    assert np.all(low < TRUTH) and np.all(TRUTH < high)
    assert np.allclose(np.log(TRUTH / low), np.log(high / TRUTH))
    assert np.allclose(np.log(high / TRUTH), Z95 * np.sqrt(np.diag(cov)))
    assert np.allclose(np.sqrt(low * high), TRUTH)
    zero_low, zero_high = intervals(TRUTH, np.zeros((N_PAR, N_PAR)))   # no noise: degenerate interval
    assert np.array_equal(zero_low, TRUTH) and np.array_equal(zero_high, TRUTH)


def test_linearised_sensitivity_is_pinv_for_unit_weights(linear_model):
    J = linear_model
    assert np.allclose(linearised_sensitivity(J), np.linalg.pinv(J))
    assert np.allclose(linearised_sensitivity(J, np.ones(N_MEAS)), np.linalg.pinv(J))
    assert np.allclose(linearised_sensitivity(J) @ J, np.eye(N_PAR))


def test_linearised_sensitivity_matches_finite_difference_resolve_with_weights(linear_model):
    J = linear_model
    w = np.random.default_rng(3).uniform(0.2, 5.0, N_MEAS)
    S = linearised_sensitivity(J, w)
    h = 1e-6
    fd = np.empty((N_PAR, N_MEAS))
    for i in range(N_MEAS):                         # re-solve with ln m_i ± h: the paper's recipe, linearised
        e = np.zeros(N_MEAS)
        e[i] = h
        plus = np.log(estimate(J, np.expm1(e)[None, :], w)[0] / TRUTH)
        minus = np.log(estimate(J, np.expm1(-e)[None, :], w)[0] / TRUTH)
        fd[:, i] = (plus - minus) / (2 * h)
    assert np.allclose(S, fd, rtol=1e-6, atol=1e-8)
    assert not np.allclose(S, np.linalg.pinv(J), atol=1e-3)        # the weights matter
    # weighted covariance: σ² S Sᵀ
    assert np.allclose(log_covariance(J, 0.1, w), 0.01 * S @ S.T)


def test_rank_deficient_jacobian_uses_the_pseudo_inverse(linear_model):
    J = linear_model.copy()
    J[:, 5] = J[:, 4]                               # two parameters indistinguishable
    s, rank, cond = conditioning(J)
    assert rank == N_PAR - 1 and cond > 1e12
    S = linearised_sensitivity(J)
    assert np.all(np.isfinite(S)) and np.allclose(S, np.linalg.pinv(J))


def test_limits_flag_only_columns_the_weighted_measurements_do_not_see(linear_model):
    from breastcore.inverse.uncertainty import (
        SEEN,
        TOWARDS_INFINITY,
        TOWARDS_ZERO,
        UNSEEN_SENSITIVITY,
        UNSEEN_UNMOVED,
        limits,
    )
    J = linear_model.copy()
    J[:, 1] *= 0.5 * UNSEEN_SENSITIVITY / np.linalg.norm(J[:, 1])      # half the threshold: unseen
    J[:, 4] *= 2.0 * UNSEEN_SENSITIVITY / np.linalg.norm(J[:, 4])      # twice it: seen, however weakly
    J[:, 5] *= 0.5 * UNSEEN_SENSITIVITY / np.linalg.norm(J[:, 5])
    initial = TRUTH.copy()
    estimate = TRUTH * np.array([1.0, 1e-20, 30.0, 0.5, 1e-9, 1e9])
    codes = limits(J, estimate, initial)
    assert codes.tolist() == [SEEN, TOWARDS_ZERO, SEEN, SEEN, SEEN, TOWARDS_INFINITY]
    assert limits(J, initial, initial)[[1, 5]].tolist() == [UNSEEN_UNMOVED, UNSEEN_UNMOVED]
    # a start already unseen that drifts at round-off, or by less than LIMIT_FACTOR, has no direction
    drift = TRUTH * np.array([1.0, 1 + 1e-13, 1.0, 1.0, 1.0, 1 / 9.0])
    assert limits(J, drift, initial)[[1, 5]].tolist() == [UNSEEN_UNMOVED, UNSEEN_UNMOVED]
    # what a measurement weighs decides what it shows: a column seen only by unweighted rows is unseen
    weights = np.ones(N_MEAS)
    weights[:7] = 0.0
    J[7:, 2] = 0.0
    assert limits(J, estimate, initial, weights)[2] == TOWARDS_INFINITY
    assert limits(J, estimate, initial)[2] == SEEN
