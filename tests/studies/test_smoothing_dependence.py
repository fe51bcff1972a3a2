"""The δ-dependence study: its difference table against hand-made measurements, and a real solve."""

import numpy as np
import pytest

from breastcore.studies import smoothing_dependence as study


def test_differences_and_slope_of_a_linear_dependence():
    limit = np.array([1.0, 2.0, -3.0])
    by_delta = {d: limit * (1 + 5.0 * d) for d in (1e-4, 1e-5, 1e-6)}   # M(δ) = M(0) (1 + 5 δ)
    diff, slope = study.differences(by_delta)
    assert set(diff) == {1e-4, 1e-5}
    assert diff[1e-4] == pytest.approx(5.0 * (1e-4 - 1e-5) / (1 + 5e-5), rel=1e-9)   # from the next smaller δ
    assert diff[1e-5] == pytest.approx(5.0 * (1e-5 - 1e-6) / (1 + 5e-6), rel=1e-9)
    assert slope == pytest.approx(1.0, abs=1e-3)
    error = 5.0 * 1e-5                                                  # of δ = 1e-5 against δ → 0
    assert diff[1e-5] == pytest.approx(0.9 * error, rel=1e-4)          # 0.9 × it, to first order in aδ
    quadratic = {d: limit * (1 + d ** 2) for d in (1e-1, 1e-2, 1e-3)}
    assert study.differences(quadratic)[1] == pytest.approx(2.0, abs=0.01)


def test_bad_arguments_are_refused():
    with pytest.raises(SystemExit):
        study.parse_args(["--deltas", "1e-6"])
    with pytest.raises(SystemExit):
        study.parse_args(["--deltas", "1e-6", "0"])
    with pytest.raises(SystemExit):
        study.parse_args(["--deltas", "1e-6", "1e-6"])                  # one δ given twice
    assert study.parse_args(["--deltas", "1e-6", "1e-4", "1e-6"]).deltas == [1e-4, 1e-6]
    assert study.parse_args(["--quick"]).levels == ["coarse"]
    assert study.parse_args([]).levels == study.LEVELS


def test_coarse_measurements_converge_linearly_as_delta_falls():
    """On coarse at Λ̄ the measurements approach their δ → 0 limit linearly (slope ≈ 1)."""
    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    from breastcore.model.postures import paper_postures
    model = ForwardModel(mesh_level("coarse"))
    by_delta = {d: study.measurements(model, Parameters(smoothing=d), paper_postures())[0] for d in (1e-4, 1e-5, 1e-6)}
    diff, slope = study.differences(by_delta)
    assert diff[1e-4] > diff[1e-5] > 0
    assert 0.8 < slope < 1.2
