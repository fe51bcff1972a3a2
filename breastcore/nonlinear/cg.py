"""The paper's baseline minimiser: non-linear conjugate gradients (section 4.2).

Polak–Ribière+ CG with restarts. The line search finds a root of the directional
derivative ``φ'(α) = ∇J(z + α d)·d`` by safeguarded secant steps, so it keeps
working where energy differences fall below round-off, and it can stop on the
same Euclidean gradient-norm tolerance as Newton: benchmarks compare like with like.
An inadmissible trial point (inverted tet) halves the step. Returns the same
:class:`~breastcore.nonlinear.newton.NewtonResult` record as Newton.
"""

from __future__ import annotations

import numpy as np

from breastcore.nonlinear.newton import NewtonResult


def _slope(problem, z, d, alpha):
    trial = z + alpha * d
    if not np.isfinite(problem.value(trial)):
        return None, None
    g = problem.gradient(trial)
    return float(g @ d), g


def _line_search(problem, z, d, slope0, g0, max_evals=30):
    """α with |φ'(α)| ≤ 0.1|φ'(0)|, or None. Returns (alpha, gradient at z + α d)."""
    eps = 1e-8 * np.linalg.norm(z) / max(np.linalg.norm(d), 1e-300)
    s_eps, _ = _slope(problem, z, d, eps)
    curvature = (s_eps - slope0) / eps if s_eps is not None else 0.0
    alpha = -slope0 / curvature if curvature > 0 else eps * 1e3
    lo, s_lo, hi, s_hi = 0.0, slope0, None, None
    for _ in range(max_evals):
        s, g = _slope(problem, z, d, alpha)
        if s is None:                      # inadmissible: the root lies before alpha
            hi, s_hi = alpha, None
        elif abs(s) <= 0.1 * abs(slope0):
            return alpha, g
        elif s < 0:
            lo, s_lo = alpha, s
        else:
            hi, s_hi = alpha, s
        if hi is None:
            alpha *= 4.0
        elif s_hi is None:
            alpha = 0.5 * (lo + hi)
        else:                              # secant on the bracket, safeguarded
            alpha = lo - s_lo * (hi - lo) / (s_hi - s_lo)
            if not lo + 0.01 * (hi - lo) < alpha < hi - 0.01 * (hi - lo):
                alpha = 0.5 * (lo + hi)
    return None, None


def conjugate_gradient(problem, z0, tolerance, max_iterations=20000):
    """Minimise ``problem`` by non-linear CG until ‖gradient‖₂ ≤ ``tolerance`` (N)."""
    z = np.array(z0, dtype=float)
    g = problem.gradient(z)
    d = -g
    history = []
    message = "iteration limit"
    for it in range(max_iterations + 1):
        g_norm = float(np.linalg.norm(g))
        history.append(g_norm)
        if g_norm <= tolerance:
            return NewtonResult(z, True, it, g_norm, tolerance, problem.value(z), 0, tuple(history), "converged")
        if it == max_iterations:
            break
        slope = float(g @ d)
        if slope >= 0:                     # not a descent direction: restart
            d, slope = -g, -float(g @ g)
        alpha, g_new = _line_search(problem, z, d, slope, g)
        if alpha is None:
            message = "line search failed"
            break
        z = z + alpha * d
        beta = max(0.0, float(g_new @ (g_new - g)) / float(g @ g))
        g, d = g_new, -g_new + beta * d
    return NewtonResult(z, False, len(history) - 1, history[-1], tolerance, problem.value(z), 0,
                        tuple(history), message)
