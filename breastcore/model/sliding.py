"""When the back plane holds the breast: the Chassaignac slip threshold (issue #18).

The smoothed Chassaignac term of spec §2 is a Tresca-type friction on the back plane
Γ_B, with the coefficient ``c`` as its slip threshold. The back can carry the weight
of the breast by friction alone only where ``c`` exceeds the mean tangential stress
that weight puts on Γ_B; below it the standing breast slides down the back and
crushes against the fixed infra-mammary fold.
"""

from __future__ import annotations

import math

from breastcore.model.geometry import base_radius, cap_volume

#: A margin below this is outside the model's mesh-converged regime: the back cannot hold the
#: standing breast by friction alone, which slides and crushes against the fold
#: (spec §2; docs/calibration in README, "The Chassaignac coefficient").
REGIME_MARGIN = 1.0


def slip_threshold(params) -> float:
    r"""The stress ``ρ g V / |Γ_B|`` at which the back plane can hold the breast's weight, Pa.

    Parameters
    ----------
    params : breastcore.model.parameters.Parameters
        Or any object with ``R``, ``H`` (m), ``density`` (kg m-3) and
        ``gravity_magnitude`` (m s-2) attributes, ``0 < H < R``.

    Returns
    -------
    float
        The threshold in Pa: 310.8 Pa at the paper's Λ̄ (R = 0.0562 m, H = 0.05 m)
        with ρ = 1000 kg m-3 and g = 9.81 m s-2.

    Raises
    ------
    ValueError
        Unless ``0 < H < R`` (from :func:`breastcore.model.geometry.check_cap`).

    Notes
    -----
    The Chassaignac energy ``Σ_T |T|/3 c Σ ||f(P) − P||`` is a dissipation-like
    term of Tresca friction: its subgradient bounds the tangential traction on Γ_B
    by ``c`` (Pa). Standing, gravity ``−g e_z`` is tangential to the back plane,
    so the whole weight ``ρ g V`` has to be carried by the back traction and the
    reaction of the fixed fold γ_D. By friction alone, the back can carry at most
    ``c |Γ_B|``, so it holds the breast without help from the fold only where

    .. math:: c \ge c^* = \frac{\rho g V}{|\Gamma_B|},
              \quad V = \frac{\pi H^2 (3R - H)}{3},
              \quad |\Gamma_B| = \pi a^2 = \pi H (2R - H),

    i.e. ``c* = ρ g H (3R − H) / (3 (2R − H))``: the weight per unit base area
    of the gravity-free cap (the mass ``ρ V`` is that of the reference
    configuration). Bent forward by θ, the tangential load is
    ``ρ g V cos θ``: standing is the worst case. Below ``c*`` the back
    slides, and the fold takes the rest of the weight in a thin layer of tets
    that crush (``det F`` ~ 1e-5 at the paper's Λ̄ with c = 100 Pa).
    """
    volume = cap_volume(params.R, params.H)
    area = math.pi * base_radius(params.R, params.H) ** 2
    return float(params.density * params.gravity_magnitude * volume / area)


def sliding_margin(params) -> float:
    r"""``c / c*``: the Chassaignac coefficient over :func:`slip_threshold` (dimensionless).

    Parameters
    ----------
    params : breastcore.model.parameters.Parameters
        As for :func:`slip_threshold`, with ``chassaignac`` (Pa).

    Returns
    -------
    float
        Above 1 the back can hold the standing breast by friction alone; below 1 it
        slides. ``inf`` where the threshold is 0 (no gravity) and ``c > 0``; NaN
        where both are 0.

    Notes
    -----
    .. math:: m = \frac{c}{\rho g V / |\Gamma_B|}
                = \frac{3 c (2R - H)}{\rho g H (3R - H)}.

    The margin depends on ``R`` and ``H`` only through ``V/|Γ_B|``, which grows
    linearly with a common scale of both: at ``R, H × 1.3`` it is the margin at
    ``R, H`` divided by 1.3.
    """
    threshold = slip_threshold(params)
    c = float(params.chassaignac)
    if threshold == 0.0:
        return math.inf if c > 0 else math.nan
    return c / threshold


def regime_warning(params) -> str:
    """A one-line warning when :func:`sliding_margin` is below :data:`REGIME_MARGIN`, else ``""``."""
    margin = sliding_margin(params)
    if not margin < REGIME_MARGIN:
        return ""
    return (f"sliding margin c/(ρ g V/|Γ_B|) = {margin:.3g} < {REGIME_MARGIN:g} (c = {params.chassaignac:g} Pa, "
            f"threshold {slip_threshold(params):.4g} Pa): the back cannot hold the standing breast, whose shape is "
            f"outside the model's mesh-converged regime")
