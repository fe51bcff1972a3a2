"""The replay of the cost_rtol stop (breastcore.studies.stopping_replay) on hand-made cost histories."""

import pytest

from breastcore.studies.stopping_replay import plateau_stop


@pytest.mark.parametrize("cost, rtol, stop", [
    ([1.0, 0.5, 0.499, 0.3], 0.01, 2),      # 0.2 % < 1 %: stops after iteration 2, not at the later big drop
    ([1.0, 0.5, 0.499, 0.3], 0.001, 3),     # 0.2 % ≥ 0.1 %: never fires, the whole run
    ([1.0, 0.995, 0.5], 0.01, 1),           # fires on the first step
    ([1.0, 0.5, 0.25], 0.0, 2),             # 0 turns it off
    ([1.0, 0.5, 0.5], 0.01, 2),             # a step with no decrease
])
def test_plateau_stop_is_the_first_small_relative_decrease(cost, rtol, stop):
    assert plateau_stop(cost, rtol) == stop
