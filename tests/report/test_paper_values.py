"""The paper's transcribed tables: checked against the averages the paper prints beside them."""

import numpy as np
import pytest

from breastcore.model.mesh import LEVEL_NODE_COUNTS
from breastcore.model.parameters import IDENTIFIED
from breastcore.report import paper_values as paper


def test_the_papers_mesh_sizes_are_our_levels():
    # the paper's tables are keyed by its node counts; each must be one of our levels
    assert {226, 572, 1014, 1404, 2127, 2498} <= set(LEVEL_NODE_COUNTS.values())


@pytest.mark.parametrize("table, printed", [
    (paper.ANNEX_A, {"coarse": 6.42, "medium-thin": 6.40, "ultra-thin": 6.25}),     # its "avg total" column
    (paper.ANNEX_B, {"coarse": 16.39, "medium-thin": 16.59, "ultra-thin": 16.25}),
])
def test_annex_parameter_rows_average_to_the_printed_total(table, printed):
    for level, total in printed.items():
        assert list(table[level]) == list(IDENTIFIED)
        assert np.mean(list(table[level].values())) == pytest.approx(total, abs=0.006)


def test_annex_measurement_rows_average_to_the_printed_total():
    printed = {"Coarse": 1.98, "Medium": 1.79, "Thin": 1.75}
    for label, values in paper.ANNEX_A_MEASUREMENTS.items():
        assert len(values) == 15
        assert np.mean(values) == pytest.approx(printed[label], abs=0.006)


def test_tables_cover_the_papers_levels():
    assert list(paper.TABLE1) == ["coarse", "medium", "medium-thin", "thin", "very-thin", "ultra-thin"]
    assert list(paper.TABLE2) == ["coarse", "medium", "medium-thin", "thin", "very-thin"]
    assert list(paper.EVOLUTION_MEAN) == list(paper.EVOLUTION_SD) == ["medium", "medium-thin", "thin", "very-thin"]
    assert paper.SENSITIVITY.shape == (15, 6)
