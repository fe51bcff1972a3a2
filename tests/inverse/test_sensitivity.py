"""The paper's finite sensitivity (re-identification with m_i × (1 ± δ))."""

from types import SimpleNamespace

import numpy as np
from linear_model import LinearModel  # tests/linear_model.py

from breastcore.forward.model import ForwardModel
from breastcore.inverse.operator import MeasurementModel
from breastcore.inverse.options import IdentificationOptions
from breastcore.inverse.sensitivity import finite_sensitivity
from breastcore.inverse.uncertainty import linearised_sensitivity
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures

TRUTH = np.array([0.0562, 0.05, 1000.0, 150.0, 8000.0, 1600.0])


def test_finite_sensitivity_tends_to_the_linearised_one_as_delta_shrinks():
    """Central differences of re-identified Λ with δ = 1e-3 and 1e-4 against (JᵀJ)⁻¹Jᵀ (inverse crime,
    coarse): the difference is the O(δ²) term, so it falls about 100× from one δ to the next.

    Measured at the default c = 500 Pa (cond J = 1.2e3): 5.8e-3 and 4.6e-5 of the largest entry
    (94, λ_s on fours' frontal depth); at c = 100 Pa (cond J = 370), 2.4e-4 with δ = 1e-3.
    """
    mm = MeasurementModel(ForwardModel(mesh_level("coarse")), Parameters(), paper_postures())
    solutions = mm.solve(TRUTH)
    target = mm.measure(solutions)
    J = (mm.implicit_jacobian(TRUTH, solutions) * TRUTH / target[..., None]).reshape(target.size, -1)
    linear = linearised_sensitivity(J)
    errors = []
    for delta in (1e-3, 1e-4):
        S, failures, limited = finite_sensitivity(mm, SimpleNamespace(values=target, weights=None), TRUTH,
                                                  IdentificationOptions(max_iterations=10), delta=delta,
                                                  processes=2)
        assert failures == 0 and limited == 0
        errors.append(np.abs(S - linear).max() / np.abs(linear).max())
    assert errors[1] <= 1e-3 and errors[1] <= errors[0] / 20, errors


def test_finite_sensitivity_is_the_same_in_any_number_of_processes_and_counts_limited_runs():
    mm = LinearModel()
    target = SimpleNamespace(values=mm.measure(mm.solve(TRUTH)), weights=None)
    runs = {p: finite_sensitivity(mm, target, TRUTH, IdentificationOptions(max_iterations=2), processes=p)
            for p in (1, 2)}
    assert np.array_equal(runs[1][0], runs[2][0]) and runs[1][1:] == runs[2][1:]
    S, failures, limited = runs[1]
    assert failures == 0 and 0 < limited <= 30           # 2 iterations cannot fit ±10 % data: kept, counted
    assert np.all(np.isfinite(S))
    full, _, none_limited = finite_sensitivity(mm, target, TRUTH, IdentificationOptions())
    assert none_limited == 0
    assert np.abs(S - full).max() > 0                      # the capped runs did stop early
