"""A posture's inertia-check factor is its Jacobian's: reused only for the same matrix, and equal
to a fresh factorisation bit for bit; each posture keeps its own PARDISO handle."""

import numpy as np
import pytest

from breastcore.forward.model import ForwardModel
from breastcore.inverse.operator import MeasurementModel
from breastcore.linalg import pardiso
from breastcore.linalg.factorization import Factorization
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="the inertia check needs PARDISO")


def _fresh_tangent(model, params, posture, position):
    problem = model.problem(params, posture)
    return Factorization(problem.hessian(problem.free(position)), problem.assembler.pattern)


def test_the_tangent_of_the_last_equilibrium_is_the_inertia_checks_factor_and_equals_a_fresh_one():
    model = ForwardModel(mesh_level("coarse"))
    params = Parameters()
    standing, fours = paper_postures()[0], paper_postures()[2]
    solution = model.solve(params, standing)
    model.solve(params, fours)                                  # another posture factorises in between
    problem, factor = model.tangent(params, standing, solution.position)
    assert factor is model._tangents["standing"][-1]            # the inertia check's factor, not a new one
    assert factor._pattern.handle(factor.mixed).owner == factor._token   # its numeric factor survived fours
    rhs = np.random.default_rng(0).standard_normal((problem.assembler.n_free, 3))
    np.testing.assert_array_equal(factor.solve(rhs), _fresh_tangent(model, params, standing,
                                                                    solution.position).solve(rhs))


def test_the_kept_factor_is_not_used_at_another_state_or_other_parameters():
    model = ForwardModel(mesh_level("coarse"))
    params = Parameters()
    standing = paper_postures()[0]
    solution = model.solve(params, standing)
    kept = model._tangents["standing"][-1]
    moved = solution.position + 1e-9
    assert model.tangent(params, standing, moved)[1] is not kept
    assert model.tangent(params.replace(mu_breast=params.mu_breast * 1.01), standing, solution.position)[1] is not kept
    assert model.tangent(params, standing, solution.position)[1] is kept
    model.release_tangents()
    assert model.tangent(params, standing, solution.position)[1] is not kept


def test_the_implicit_jacobian_is_unchanged_by_the_reuse(monkeypatch):
    model = ForwardModel(mesh_level("coarse"))
    mm = MeasurementModel(model, Parameters(), paper_postures())
    values = np.array(Parameters().identified())
    solutions = mm.solve(values)
    reused = mm.implicit_jacobian(values, solutions)
    monkeypatch.setattr(model, "_tangents", {})
    np.testing.assert_array_equal(mm.implicit_jacobian(values, solutions), reused)


def test_releasing_the_other_slots_keeps_one_postures_factors_and_every_analysis():
    model = ForwardModel(mesh_level("coarse"))
    params = Parameters()
    solved = {p.name: model.solve(params, p) for p in paper_postures()}
    fold = params.fold_angle
    held = {name: [h.numeric for h in model.pattern(fold, name)._handles.values()] for name in solved}
    assert all(any(flags) for flags in held.values()) and set(model._tangents) == set(solved)
    model.release_other_slots("bent45")
    for name in solved:
        handles = model.pattern(fold, name)._handles.values()
        assert all(h.analysed for h in handles)
        assert any(h.numeric for h in handles) == (name == "bent45")
    assert set(model._tangents) == {"bent45"}
    problem, factor = model.tangent(params, paper_postures()[0], solved["standing"].position)   # refactorised
    assert factor.negative_pivots == 0
