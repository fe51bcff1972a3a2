"""The Chassaignac slip threshold ρ g V/|Γ_B| and the sliding margin (issue #18)."""

import math

import numpy as np
import pytest

from breastcore.model.parameters import Parameters
from breastcore.model.sliding import sliding_margin, slip_threshold


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


def test_the_regime_warning_fires_below_the_bound_and_not_above():
    from breastcore.model.sliding import REGIME_MARGIN, regime_warning, sliding_margin, slip_threshold
    base = Parameters()
    threshold = slip_threshold(base)
    below = base.replace(chassaignac=0.99 * REGIME_MARGIN * threshold)
    above = base.replace(chassaignac=1.01 * REGIME_MARGIN * threshold)
    assert sliding_margin(below) < REGIME_MARGIN < sliding_margin(above)
    assert "sliding margin" in regime_warning(below) and "0.99" in regime_warning(below)
    assert regime_warning(above) == ""


def test_solutions_and_estimates_record_their_margin_and_warning(tmp_path):
    """A patient estimate below the bound warns in its dataset, its log and show; one above does not."""
    import logging

    from breastcore.cli.browse import describe
    from breastcore.inverse.identify import identify
    from breastcore.inverse.measurements import QUANTITIES
    from breastcore.inverse.operator import MeasurementModel
    from breastcore.inverse.options import IdentificationOptions
    from breastcore.io.identification import identification_dataset
    from breastcore.io.patient import PatientMeasurements
    from breastcore.model.mesh import mesh_level
    from breastcore.model.postures import paper_postures
    from breastcore.model.sliding import sliding_margin
    from breastcore.problem import ProblemSpec
    from breastcore.stages.identify import log_verdict
    mesh = mesh_level("coarse")
    for c, warned in ((100.0, True), (2000.0, False)):
        problem = ProblemSpec(parameters=Parameters(chassaignac=c), postures=paper_postures(),
                              measurement_set="paper15", identification=IdentificationOptions(max_iterations=1))
        mm = MeasurementModel.from_problem(problem, mesh)
        truth = np.array(problem.parameters.identified())
        data = mm.measure(mm.solve(truth))
        target = PatientMeasurements(paper_postures(), QUANTITIES, data)
        result = identify(mm, data, truth, problem.identification)
        ds = identification_dataset(result, mm, target, problem, initial=truth)
        assert float(ds["sliding_margin"]) == pytest.approx(sliding_margin(problem.parameters), rel=1e-12)
        assert bool(ds.attrs["regime_warning"]) == warned
        assert ("WARNING: sliding margin" in describe(ds)) == warned
        records = []
        handler = logging.Handler()
        handler.emit = records.append
        logging.getLogger("breastcore").addHandler(handler)
        try:
            log_verdict(ds)
        finally:
            logging.getLogger("breastcore").removeHandler(handler)
        assert any("sliding margin" in r.getMessage() for r in records) == warned
