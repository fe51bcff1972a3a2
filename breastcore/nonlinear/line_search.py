"""The backtracking line search of Newton's method, its descent test, and BLAS-free vector helpers."""

from __future__ import annotations

import numpy as np


def _dot(a, b):
    """``a · b`` without BLAS (a threaded BLAS dot stalls when the other core is busy)."""
    return float(np.einsum("i,i->", a, b))


def _norm(a):
    """Euclidean norm of a vector, without BLAS (see :func:`_dot`)."""
    return float(np.sqrt(np.einsum("i,i->", a, a)))


def _line_search(problem, z, d, energy, g, g_norm, min_step=2.0**-30, expand=False):
    """Backtracking search on ``problem.value``; returns (step, z_new, energy_new) or None.

    With ``expand``, an accepted full step is doubled (up to 2¹⁰) while the energy keeps
    decreasing. Used for the modified (projected or shifted) Hessians only: near a
    saddle their step along the escape direction is far too short, and without
    expansion leaving the saddle took up to 100 iterations of growing gradient.
    """
    slope = _dot(g, d)
    scale = abs(energy) + problem.energy_scale
    step = 1.0
    while step >= min_step:
        z_new = z + step * d
        e_new = problem.value(z_new)
        if np.isfinite(e_new):
            if e_new <= energy + 1e-4 * step * slope:
                if expand and step == 1.0:
                    while step < 2.0**10:
                        z_try = z + 2.0 * step * d
                        e_try = problem.value(z_try)
                        if not (np.isfinite(e_try) and e_try < e_new):
                            break
                        step, z_new, e_new = 2.0 * step, z_try, e_try
                return step, z_new, e_new
            # Below round-off the energy cannot rank the two points: use the gradient.
            if abs(e_new - energy) <= 1e-12 * scale and abs(step * slope) <= 1e-11 * scale:
                if _norm(problem.gradient(z_new)) < g_norm:
                    return step, z_new, e_new
        step *= 0.5
    return None


def descends(g, g_norm, d):
    """Whether ``d`` is a descent direction for the gradient ``g`` (beyond round-off)."""
    return not _dot(g, d) >= -1e-12 * g_norm * _norm(d)
