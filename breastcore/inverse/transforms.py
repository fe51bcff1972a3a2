"""The unconstrained variables of the identification: ``z = (ln R, logit(H/R), ln λ, ln μ, ln λ_s, ln μ_s)``.

The bounds ``R > 0``, ``0 < H < R`` and positive moduli hold for every ``z``, and the log
scaling makes the six columns of the Jacobian comparable.
"""

from __future__ import annotations

import numpy as np


def to_unconstrained(values):
    """``z`` of ``Λ = values`` (SI)."""
    R, H, *moduli = np.asarray(values, float)
    s = H / R
    return np.array([np.log(R), np.log(s / (1 - s)), *np.log(moduli)])


def from_unconstrained(z):
    """``Λ`` (SI) of ``z``; the inverse of :func:`to_unconstrained`."""
    z = np.asarray(z, float)
    R = np.exp(z[0])
    return np.array([R, R / (1 + np.exp(-z[1])), *np.exp(z[2:])])


def unconstrained_chain(values):
    """``dΛ/dz`` (6×6) of :func:`from_unconstrained` at ``Λ = values``."""
    R, H = values[0], values[1]
    s = H / R
    T = np.diag(np.asarray(values, float))
    T[1, 1] = R * s * (1 - s)
    T[1, 0] = H
    return T
