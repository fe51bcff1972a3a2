"""The Chassaignac slip threshold ρ g V/|Γ_B| and the sliding margin (issue #18)."""

import math

import pytest

from breastcore.parameters import Parameters
from breastcore.sliding import sliding_margin, slip_threshold


def test_slip_threshold_is_the_weight_per_base_area_of_the_undeformed_cap():
    R, H, rho, g = 0.0562, 0.05, 1000.0, 9.81
    volume = math.pi * H**2 * (3 * R - H) / 3                     # spherical cap
    base = math.pi * (R**2 - (R - H) ** 2)                        # the disk where the plane y = 0 cuts the sphere
    by_hand = rho * g * volume / base
    assert by_hand == pytest.approx(310.8, abs=0.05)              # issue #18: "≈ 311 Pa at Λ̄"
    assert slip_threshold(Parameters()) == pytest.approx(by_hand, rel=1e-12)
    assert sliding_margin(Parameters(chassaignac=300.0)) == pytest.approx(300.0 / by_hand, rel=1e-12)
    assert sliding_margin(Parameters(chassaignac=100.0)) < 1 < sliding_margin(Parameters(chassaignac=1000.0))


def test_slip_threshold_scales_with_size_density_and_gravity():
    base = Parameters()
    assert slip_threshold(base.replace(R=1.3 * base.R, H=1.3 * base.H)) == pytest.approx(1.3 * slip_threshold(base))
    assert slip_threshold(base.replace(density=500.0, gravity_magnitude=2 * 9.81)) == \
        pytest.approx(slip_threshold(base))
    assert sliding_margin(base.replace(gravity_magnitude=0.0)) == math.inf
    with pytest.raises(ValueError, match="H"):
        slip_threshold(type("P", (), {"R": 0.05, "H": 0.06, "density": 1000.0, "gravity_magnitude": 9.81})())
