"""The reduced-space start of far solves (issue #21), and its use in an identification."""

import numpy as np
import pytest

from breastcore.forward.model import ForwardModel
from breastcore.forward.options import SolverOptions
from breastcore.forward.reduced import reduced_start
from breastcore.inverse.identify import identify
from breastcore.inverse.operator import MeasurementModel
from breastcore.inverse.options import IdentificationOptions
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures

TRUTH = np.array(Parameters().identified())


@pytest.fixture(scope="module")
def model():
    return ForwardModel(mesh_level("coarse"))


def test_an_equilibrium_in_the_span_is_recovered(model):
    """With the equilibrium's own displacement in the basis, the reduced minimiser is that equilibrium."""
    params, posture = Parameters(), paper_postures()[0]
    solution = model.solve(params, posture)
    u = solution.position - model.reference(params.R, params.H)
    x = reduced_start(model, params, posture, [u])
    scale = np.abs(u).max()
    assert np.abs(x - solution.position).max() <= 1e-5 * scale
    other = model.solve(params.with_identified(TRUTH * 1.1), posture)   # a second snapshot does not spoil it
    u2 = other.position - model.reference(*(TRUTH[:2] * 1.1))
    x2 = reduced_start(model, params, posture, [u2, u])
    assert np.abs(x2 - solution.position).max() <= 1e-5 * scale


def test_a_far_solve_from_the_reduced_start_starts_closer_and_lands_on_the_cold_equilibrium(model):
    """From snapshots 20-30 % away, the reduced start is nearer the equilibrium than the reference
    state (the cold start) and than either snapshot's displacement, and Newton goes from it to
    the cold solve's equilibrium. (Iterations are no measure on coarse: at c = 500 Pa without a
    δ phase its cold solves take one load step of ~10 Newton iterations.)"""
    for posture in paper_postures():
        snapshots = []
        for factor in (0.8, 1.25):
            p = Parameters().with_identified(TRUTH * factor)
            snapshots.append(model.solve(p, posture).position - model.reference(p.R, p.H))
        target = Parameters().with_identified(TRUTH * np.array([1.0, 0.95, 1.2, 0.9, 1.1, 1.05]))
        cold = model.solve(target, posture)
        reference = model.reference(target.R, target.H)

        def distance(x):
            return np.abs(x - cold.position).max()
        start = reduced_start(model, target, posture, snapshots)
        assert distance(start) < 0.5 * min(distance(reference + u) for u in snapshots)
        assert distance(start) < 0.1 * distance(reference)
        warm = model.solve(target, posture, start)
        assert warm.continuation_steps == 1                      # the direct attempt converged
        assert distance(warm.position) <= 1e-8


def test_identification_with_reduced_starts_recovers_the_truth_and_checks_its_branch(model, monkeypatch):
    mm = MeasurementModel(model, Parameters(), paper_postures(), reduced_snapshots=4)
    target = mm.measure(mm.solve(TRUTH))
    initial = TRUTH * np.array([1.3, 0.7, 0.7, 1.3, 1.3, 0.7])
    calls = []
    original = MeasurementModel._reduced_starts
    monkeypatch.setattr(MeasurementModel, "_reduced_starts", lambda self, *a: calls.append(1) or original(self, *a))
    result = identify(mm, target, initial, IdentificationOptions(reduced_snapshots=4))
    assert calls, "no trial point was started from the reduced space"
    assert np.abs(result.estimate / TRUTH - 1).max() <= 1e-6


def test_reduced_snapshots_must_be_a_non_negative_integer():
    for bad in (-1, 1.5):
        with pytest.raises(ValueError):
            IdentificationOptions(reduced_snapshots=bad)
