"""Tangent starts: warm starts from the first-order predictor ``x⁰ + ∂x/∂Λ (Λ − Λ⁰)`` (issue #21)."""

import numpy as np
import pytest

from breastcore.forward.model import ForwardModel
from breastcore.inverse.identify import identify
from breastcore.inverse.operator import MeasurementModel
from breastcore.inverse.options import IdentificationOptions
from breastcore.inverse.warm_start import WarmStarts
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import IDENTIFIED, Parameters
from breastcore.model.postures import paper_postures

TRUTH = np.array(Parameters().identified())


@pytest.fixture(scope="module")
def coarse():
    """A coarse measurement model, its equilibria at Λ̄ and their tangents ``∂x/∂Λ``."""
    mm = MeasurementModel(ForwardModel(mesh_level("coarse")), Parameters(), paper_postures())
    solutions = mm.solve(TRUTH)
    tangents = {}
    mm.implicit_jacobian(TRUTH, solutions, tangents=tangents)
    return mm, solutions, tangents


def test_tangents_match_central_differences_of_the_equilibria(coarse):
    mm, solutions, tangents = coarse
    warm = WarmStarts.at(np.inf, solutions, TRUTH)
    for j, name in enumerate(IDENTIFIED):
        step = 1e-5 * TRUTH[j] * np.eye(6)[j]
        plus, minus = mm.solve(TRUTH + step, warm), mm.solve(TRUTH - step, warm)
        for posture, tangent in tangents.items():
            assert tangent.shape == solutions[posture].position.shape + (6,)
            central = (plus[posture].position - minus[posture].position) / (2 * step[j])
            assert np.abs(central).max() > 0, (name, posture)
            assert np.abs(tangent[..., j] - central).max() <= 1e-5 * np.abs(central).max(), (name, posture)


def _positions(shape=(4, 3), seed=0):
    rng = np.random.default_rng(seed)
    return {"standing": rng.normal(size=shape), "fours": rng.normal(size=shape)}


class _Named:
    def __init__(self, name):
        self.name = name


class _Solution:
    def __init__(self, position):
        self.position = position


POSTURES = (_Named("standing"), _Named("fours"))


def _warm(tangent_starts=True, radius=0.05):
    positions = _positions()
    warm = WarmStarts(radius, tangent_starts=tangent_starts)
    warm.remember({k: _Solution(v) for k, v in positions.items()}, TRUTH)
    tangents = {k: np.random.default_rng(1).normal(size=v.shape + (6,)) for k, v in positions.items()}
    return warm, positions, tangents


@pytest.mark.parametrize("distance", [0.01, 0.3])       # within the warm radius and beyond it
def test_the_start_is_the_first_order_predictor_near_and_far(distance):
    warm, positions, tangents = _warm()
    warm.remember_tangents(TRUTH, tangents)
    values = TRUTH * (1 + distance * np.linspace(-1, 1, 6))
    starts = warm.starts(values, POSTURES)
    for name in positions:
        np.testing.assert_allclose(starts[name], positions[name] + tangents[name] @ (values - TRUTH), rtol=1e-14)
    without = warm.starts(values, POSTURES, predict=False)
    for name in positions:
        assert (without[name] is positions[name]) if distance < 0.05 else without[name] is None


@pytest.mark.parametrize("case", ["option off", "radius 0", "other point", "moved on", "other branch"])
def test_tangents_are_not_used_where_they_do_not_belong(case):
    warm, positions, tangents = _warm(tangent_starts=case != "option off", radius=0.0 if case == "radius 0" else 0.05)
    warm.remember_tangents(TRUTH * (1.01 if case == "other point" else 1.0), tangents)
    if case in ("moved on", "other branch"):    # new equilibria: the old tangents predict from the wrong state
        assert warm.tangents != {}
        warm.remember({k: _Solution(v + 1) for k, v in positions.items()}, TRUTH * (1.02 if case == "moved on" else 1))
    assert warm.tangents == {}
    values = warm.values * 1.001
    assert all(np.array_equal(s, warm.positions[n]) or s is None for n, s in warm.starts(values, POSTURES).items())


def test_the_same_equilibrium_remembered_again_keeps_its_tangents():
    warm, positions, tangents = _warm()
    warm.remember_tangents(TRUTH, tangents)
    warm.remember({k: _Solution(v) for k, v in warm.positions.items()}, TRUTH)
    assert warm.tangents.keys() == tangents.keys()


@pytest.mark.parametrize("distance", [0.01, 0.3])
def test_a_predictor_that_inverts_a_tet_is_replaced_by_the_start_without_it(coarse, monkeypatch, distance):
    """Within the radius the fallback is the plain warm start; beyond it, the reduced-space start."""
    mm, solutions, tangents = coarse
    warm = mm.warm_starts()
    warm.remember(solutions, TRUTH)
    warm.remember_tangents(TRUTH, {name: 1e4 * t for name, t in tangents.items()})   # a wild predictor
    values = TRUTH * (1 + distance)
    wild = warm.starts(values, mm.postures)
    started = {}
    solve = mm.model.solve

    def spy(params, posture, start=None):
        started[posture.name] = start
        return solve(params, posture, start)

    monkeypatch.setattr(mm.model, "solve", spy)
    solved = mm.solve(values, warm)
    for posture in mm.postures:
        problem = mm.model.problem(mm.params(values), posture)
        assert not np.isfinite(problem.value(problem.free(wild[posture.name])))      # the predictor inverts
        start = started[posture.name]
        if distance < mm.warm_radius:
            assert start is solutions[posture.name].position
        else:
            assert start is not None and np.isfinite(problem.value(problem.free(start)))   # the reduced start
        assert not solved[posture.name].cold_start


def test_identification_with_tangent_starts_reaches_the_same_estimate_with_them_in_use(coarse, monkeypatch):
    mm, solutions, _ = coarse
    target = mm.measure(solutions)
    start = TRUTH * np.array([1.3, 0.75, 0.7, 1.3, 1.25, 0.7])
    predicted, used = [], []                  # ids of predicted starts; whether a solve started from one
    starts, solve = WarmStarts.starts, mm.model.solve

    def spy_starts(self, values, postures, predict=True):
        out = starts(self, values, postures, predict)
        if predict and self.tangents:
            predicted.extend(id(x) for x in out.values())
        return out

    def spy_solve(params, posture, start=None):
        used.append(start is not None and id(start) in predicted)
        return solve(params, posture, start)

    monkeypatch.setattr(WarmStarts, "starts", spy_starts)
    monkeypatch.setattr(mm.model, "solve", spy_solve)
    estimates = {}
    for tangent_starts in (False, True):
        predicted.clear()
        used.clear()
        model = MeasurementModel(mm.model, mm.base, mm.postures, tangent_starts=tangent_starts)
        result = identify(model, target, start, IdentificationOptions(tangent_starts=tangent_starts))
        assert result.success
        assert any(used) == tangent_starts
        estimates[tangent_starts] = result.estimate
    assert np.abs(estimates[True] / TRUTH - 1).max() <= 1e-4
    assert np.abs(estimates[True] / estimates[False] - 1).max() <= 1e-6
    with pytest.raises(ValueError, match="tangent_starts"):
        identify(MeasurementModel(mm.model, mm.base, mm.postures, tangent_starts=False), target, start)
    with pytest.raises(ValueError, match="tangent_starts"):
        IdentificationOptions(tangent_starts="yes")
