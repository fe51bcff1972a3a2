"""The rule that picks the default Chassaignac c from a table of checks (issue #18), on tables made by hand."""

import numpy as np
import pandas as pd
import pytest

from breastcore.studies.chassaignac_rule import CalibrationError, choose_chassaignac


def _table(rows):
    return pd.DataFrame(rows, columns=["chassaignac", "criterion", "where", "value"])


def _full(c, det=0.5, diff=1e-3, nl=1e-10):
    """Every criterion of one c, two rows each; the first row of each carries the given value."""
    return [(c, "min_det_F", "standing on thin at truth", det), (c, "min_det_F", "standing on reference at truth", 0.4),
            (c, "sliding_difference", "very-thin against reference at truth", diff),
            (c, "sliding_difference", "very-thin against reference at R×1.3", 2e-3),
            (c, "nonlinearity", "R on thin at the truth", 1e-11),
            (c, "nonlinearity", "mu_breast on thin at the truth", nl)]


def test_the_rule_picks_the_smallest_c_that_passes_and_names_what_fails_where():
    table = _table(_full(100.0, det=1e-5) + _full(300.0, nl=8.4e-4) + _full(1000.0) + _full(5000.0))
    choice = choose_chassaignac(table, min_det_F=0.01, max_sliding_difference=0.01, linear_threshold=1e-8)
    assert choice.chassaignac == 1000.0
    assert choice.passed[100.0] == {"min_det_F": False, "sliding_difference": True, "nonlinearity": True}
    assert choice.passed[300.0]["nonlinearity"] is False and all(choice.passed[5000.0].values())
    assert len(choice.failures[100.0]) == 1 and "(a)" in choice.failures[100.0][0]
    assert "1e-05 < 0.01 at standing on thin at truth" in choice.failures[100.0][0]
    assert "0.00084 > 1e-08 at mu_breast on thin at the truth" in choice.failures[300.0][0]
    assert choice.failures[1000.0] == [] and "1000 Pa" in choice.describe()
    # looser bounds move the choice down; rows in any order give the same answer
    assert choose_chassaignac(table.sample(frac=1, random_state=0), linear_threshold=1e-3).chassaignac == 300.0
    assert choose_chassaignac(table, min_det_F=1e-6, linear_threshold=1e-3).chassaignac == 100.0


def test_the_rule_takes_the_smallest_passing_c_even_if_a_larger_one_fails():
    choice = choose_chassaignac(_table(_full(200.0) + _full(700.0, diff=0.05)))
    assert choice.chassaignac == 200.0 and choice.passed[700.0]["sliding_difference"] is False
    assert "(b)" in choice.failures[700.0][0] and "0.05 > 0.01" in choice.failures[700.0][0]


def test_the_rule_reports_none_when_no_c_passes():
    choice = choose_chassaignac(_table(_full(100.0, det=1e-5) + _full(300.0, diff=0.02) + _full(1000.0, nl=1e-6)))
    assert choice.chassaignac is None
    assert "no c of the grid" in choice.describe()
    assert [len(f) for f in choice.failures.values()] == [1, 1, 1]


def test_a_failed_solve_or_a_missing_criterion_fails_and_a_bound_itself_passes():
    rows = (_full(100.0, det=float("nan")) + [r for r in _full(300.0) if r[1] != "nonlinearity"]
            + _full(1000.0, det=0.01))
    choice = choose_chassaignac(_table(rows))
    assert "without a value" in choice.failures[100.0][0] and "standing on thin at truth" in choice.failures[100.0][0]
    assert choice.failures[300.0] == ["(c) uniqueness-probe nonlinearity: no data"]
    assert choice.chassaignac == 1000.0                          # det F = 0.01 meets "≥ 0.01"
    assert choice.table["passed"].dtype == bool and (~choice.table["passed"]).sum() == 1


def test_the_rule_refuses_a_table_it_cannot_read():
    with pytest.raises(CalibrationError, match="unknown criterion 'volume'"):
        choose_chassaignac(_table([(100.0, "volume", "x", 1.0)]))
    with pytest.raises(CalibrationError, match="where"):
        choose_chassaignac(pd.DataFrame({"chassaignac": [1.0], "criterion": ["min_det_F"], "value": [1.0]}))
    with pytest.raises(CalibrationError, match="finite"):
        choose_chassaignac(_table([(float("inf"), "min_det_F", "x", 1.0)]))


def test_criterion_b_is_what_sliding_adds_to_the_meshes_own_gap():
    """Measured: very-thin is 1.6 % from the reference at R, H × 1.3 whatever c (5000 Pa too), a floor no c
    removes; sliding adds 13 points at c = 300 Pa. The rule must see the second, not the first."""
    from breastcore.report.calibration import criteria_table
    c_values = np.array([300.0, 500.0, 5000.0])
    gap = np.array([[0.005, 0.146], [0.004, 0.018], [0.004, 0.016]])          # (c, point): truth, R,H × 1.3
    spec = {"det_F_posture": "standing", "compare_level": "very-thin", "reference": "reference", "probe_level": "thin"}
    standing = np.full((3, 2, 2), 0.05)
    table = criteria_table(c_values, ["very-thin", "reference"], ["truth", "R×1.3 H×1.3"], np.array([True, True]),
                           standing, gap - gap[-1], np.zeros((3, 6)), spec)
    choice = choose_chassaignac(table, min_det_F=0.01, max_sliding_difference=0.01, linear_threshold=1e-8)
    assert choice.chassaignac == 500.0 and not choice.passed[300.0]["sliding_difference"]
    assert "0.13 > 0.01 at very-thin against reference at R×1.3 H×1.3" in choice.failures[300.0][0]
    absolute = criteria_table(c_values, ["very-thin", "reference"], ["truth", "R×1.3 H×1.3"], np.array([True, True]),
                              standing, gap, np.zeros((3, 6)), spec)
    assert choose_chassaignac(absolute, max_sliding_difference=0.01).chassaignac is None   # the floor blocks all
