"""The paper's finite sensitivity (re-identification with m_i × (1 ± δ)) and fork_map."""

from types import SimpleNamespace

import numpy as np

from breastcore.forward import ForwardModel
from breastcore.identify import IdentificationOptions
from breastcore.mesh import mesh_level
from breastcore.observation import MeasurementModel
from breastcore.parallel import fork_map
from breastcore.parameters import Parameters
from breastcore.postures import paper_postures
from breastcore.sensitivity import finite_sensitivity
from breastcore.uncertainty import linearised_sensitivity

TRUTH = np.array([0.0562, 0.05, 1000.0, 150.0, 8000.0, 1600.0])


def test_fork_map_keeps_order_and_closes_over_unpicklable_state():
    state = {"lock": __import__("threading").Lock(), "offset": 10}   # a Lock cannot be pickled
    serial = fork_map(lambda i: (i + state["offset"], i * i), 7, processes=1)
    forked = fork_map(lambda i: (i + state["offset"], i * i), 7, processes=2)
    assert forked == serial == [(i + 10, i * i) for i in range(7)]


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
