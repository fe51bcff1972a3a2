"""The paper's finite sensitivity (re-identification with m_i × (1 ± δ))."""

from types import SimpleNamespace

import numpy as np

from breastcore.forward import ForwardModel
from breastcore.identify import IdentificationOptions
from breastcore.mesh import mesh_level
from breastcore.observation import MeasurementModel
from breastcore.parameters import Parameters
from breastcore.postures import paper_postures
from breastcore.sensitivity import finite_sensitivity
from breastcore.uncertainty import linearised_sensitivity

from linear_model import LinearModel  # tests/linear_model.py

TRUTH = np.array([0.0562, 0.05, 1000.0, 150.0, 8000.0, 1600.0])


def test_finite_sensitivity_tends_to_the_linearised_one_as_delta_shrinks():
    """Central differences of re-identified Λ with δ = 1e-3 against (JᵀJ)⁻¹Jᵀ (inverse crime, coarse).

    Measured: 2.4e-4 of the largest entry (δ = 1e-2 gives 1.7e-2: the O(δ²) term).
    """
    mm = MeasurementModel(ForwardModel(mesh_level("coarse")), Parameters(), paper_postures())
    solutions = mm.solve(TRUTH)
    target = mm.measure(solutions)
    J = (mm.implicit_jacobian(TRUTH, solutions) * TRUTH / target[..., None]).reshape(target.size, -1)
    linear = linearised_sensitivity(J)
    S, failures, limited = finite_sensitivity(mm, SimpleNamespace(values=target, weights=None), TRUTH,
                                              IdentificationOptions(max_iterations=10), delta=1e-3, processes=2)
    assert failures == 0 and limited == 0
    assert np.abs(S - linear).max() <= 1e-3 * np.abs(linear).max()


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
