"""Saddle points: detection by the Hessian's inertia and the escape to a minimum."""

import dataclasses

import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse as sp

from breastcore.linalg import factorization, pardiso
from breastcore.nonlinear import newton as solver
from breastcore.nonlinear.saddle import escape_saddle, negative_curvature_directions

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="the inertia needs MKL PARDISO")


class DoubleWell:
    """E(x, y) = x² − y² + y⁴: a saddle at 0, minima at (0, ±1/√2) with E = −1/4."""

    energy_scale = 1.0
    length_scale = 1.0
    pattern = None

    def value(self, z):
        x, y = z
        return x * x - y * y + y ** 4

    def gradient(self, z):
        x, y = z
        return np.array([2 * x, -2 * y + 4 * y ** 3])

    def hessian(self, z, project=False):
        H = np.diag([2.0, -2.0 + 12 * z[1] ** 2])
        if project:
            H = np.maximum(H, 0.0)
        return sp.csr_matrix(H)


def test_escape_from_an_analytic_saddle_reaches_a_minimum():
    problem = DoubleWell()
    at_saddle = solver.newton(problem, np.array([0.3, 0.0]), 1e-12)
    assert at_saddle.success and np.allclose(at_saddle.x, 0.0) and at_saddle.negative_pivots == 1
    result = escape_saddle(problem, at_saddle)
    assert result.success and result.negative_pivots == 0
    assert abs(abs(result.x[1]) - 2 ** -0.5) < 1e-10 and abs(result.x[0]) < 1e-10
    assert result.energy == pytest.approx(-0.25, abs=1e-14)


class DoubleSaddle(DoubleWell):
    """E(x, y) = −x² + x⁴ − y² + y⁴: inertia 2 at 0, saddles of inertia 1 at (±1/√2, 0), (0, ±1/√2),
    minima at (±1/√2, ±1/√2) with E = −1/2."""

    def value(self, z):
        return float(np.sum(-z * z + z ** 4))

    def gradient(self, z):
        return -2 * z + 4 * z ** 3

    def hessian(self, z, project=False):
        H = -2.0 + 12 * z ** 2
        return sp.diags(np.maximum(H, 0.0) if project else H, format="csr")


def test_escape_follows_every_negative_direction_in_one_round(monkeypatch):
    """Leaving along the lowest direction only would stop on an inertia-1 saddle and need a second eigen-solve."""
    import breastcore.nonlinear.saddle as saddle
    calls = []
    original = saddle.negative_curvature_directions
    monkeypatch.setattr(saddle, "negative_curvature_directions",
                        lambda K, count, pattern=None: calls.append(count) or original(K, count, pattern))
    problem = DoubleSaddle()
    at_saddle = solver.newton(problem, np.zeros(2), 1e-12)          # g = 0: converged, on the saddle
    inertia = factorization.Factorization(problem.hessian(at_saddle.x)).negative_pivots
    at_saddle = dataclasses.replace(at_saddle, negative_pivots=inertia)
    assert at_saddle.success and np.allclose(at_saddle.x, 0.0) and at_saddle.negative_pivots == 2
    result = escape_saddle(problem, at_saddle)
    assert result.success and result.negative_pivots == 0
    assert np.allclose(np.abs(result.x), 2 ** -0.5, atol=1e-10)
    assert result.energy == pytest.approx(-0.5, abs=1e-14)
    assert calls == [2]


def test_negative_curvature_directions_match_dense_eigenpairs():
    rng = np.random.default_rng(3)
    n = 400
    A = sp.random(n, n, density=0.08, random_state=rng)
    K = (A + A.T + sp.diags(np.linspace(0.02, 300.0, n))).tocsr()
    K = K - 1.5 * sp.identity(n, format="csr")                  # a few eigenvalues below zero
    dense_values, dense_vectors = sl.eigh(K.toarray())
    count = int(np.sum(dense_values < 0))
    assert count >= 1
    values, vectors = negative_curvature_directions(K, count)
    assert np.allclose(np.sort(values), dense_values[:count], rtol=1e-8, atol=1e-10)
    for value, v in zip(values, vectors.T):
        assert np.linalg.norm(K @ v - value * v) <= 1e-7 * abs(dense_values).max()


def test_refined_mesh_solve_returns_a_stable_minimum():
    """thin, bent45: plain Newton ends on a saddle (κ ≈ −3 N/m); the solve must not."""
    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    from breastcore.model.postures import parse_posture
    mesh = mesh_level("thin")
    model = ForwardModel(mesh)
    params, posture = Parameters(), parse_posture("bent45")
    solution = model.solve(params, posture)
    again = ForwardModel(mesh).solve(params, posture)           # the escape is reproducible (fixed Lanczos start)
    assert np.array_equal(again.position, solution.position)
    problem = model.problem(params, posture)
    z = problem.free(solution.position)
    plain = solver.newton(problem, z, solution.tolerance)        # independent check of the inertia
    assert plain.success and plain.iterations == 0
    inertia = factorization.Factorization(problem.hessian(z)).negative_pivots
    assert inertia == 0 and solution.negative_eigenvalues == 0
    assert np.linalg.norm(problem.gradient(z)) <= solution.tolerance


def test_shift_diagonal_keeps_the_pattern_and_adds_sigma_identity():
    K = sp.csr_matrix((np.r_[4.0, 0.0, 1.0, 2.0, 0.0, 1.0, 3.0], [0, 1, 2, 1, 2, 0, 2], [0, 3, 5, 7]), shape=(3, 3))
    shifted = factorization.shift_diagonal(K, -1.5)                    # K has explicit zeros, which K - 1.5 I drops
    assert np.array_equal(shifted.indices, K.indices) and np.array_equal(shifted.indptr, K.indptr)
    assert np.allclose(shifted.toarray(), K.toarray() - 1.5 * np.eye(3))
    pattern = pardiso.SymmetricPattern(K.indptr, K.indices, 3)
    assert pattern.matches(shifted) and not pattern.matches((K - 1.5 * sp.identity(3)).tocsr())


def test_failed_last_round_returns_the_converged_saddle_not_a_failure(monkeypatch):
    from breastcore.nonlinear import saddle
    problem = DoubleWell()
    at_saddle = solver.newton(problem, np.array([0.3, 0.0]), 1e-12)
    real_newton = saddle.newton
    calls = []

    def stalling_newton(problem, z0, tolerance, max_iterations=50, avoid_saddles=False):
        calls.append((max_iterations, avoid_saddles))
        result = real_newton(problem, z0, tolerance, 0, avoid_saddles)   # no iteration: not converged
        assert not result.success
        return result

    monkeypatch.setattr(saddle, "newton", stalling_newton)
    result = escape_saddle(problem, at_saddle, max_iterations=100, max_rounds=1)
    assert calls == [(saddle.AVOID_ITERATIONS, True)]
    assert result.success and result.negative_pivots == 1 and np.array_equal(result.x, at_saddle.x)


class FlatWell(DoubleWell):
    """E(x, y) = x² − ε y² + y⁴ with ε = 1e-7: a negative curvature far below the stiffness."""

    def value(self, z):
        x, y = z
        return x * x - 1e-7 * y * y + y ** 4

    def gradient(self, z):
        x, y = z
        return np.array([2 * x, -2e-7 * y + 4 * y ** 3])

    def hessian(self, z, project=False):
        return sp.csr_matrix(np.diag([2.0, -2e-7 + 12 * z[1] ** 2]))


def test_a_neutral_direction_is_not_escaped():
    from breastcore.nonlinear.saddle import NEUTRAL_CURVATURE
    problem = FlatWell()
    at_saddle = solver.newton(problem, np.array([0.3, 0.0]), 1e-14)
    assert at_saddle.success and at_saddle.negative_pivots == 1
    assert 2e-7 < NEUTRAL_CURVATURE * 1.0                       # median |diagonal| is ~1
    result = escape_saddle(problem, at_saddle)
    assert np.array_equal(result.x, at_saddle.x) and result.negative_pivots == 1
    assert escape_saddle(DoubleWell(), solver.newton(DoubleWell(), np.array([0.3, 0.0]), 1e-12)).negative_pivots == 0


class NoisyBowl:
    """E = ½|z|² whose gradient carries a 1e-9 error that varies with z like round-off does."""

    energy_scale = 1.0
    length_scale = 1.0
    pattern = None

    def value(self, z):
        return 0.5 * float(z @ z)

    def __init__(self):
        self.rng = np.random.default_rng(0)

    def gradient(self, z):
        return z + 1e-9 * self.rng.standard_normal(z.size)

    def hessian(self, z, project=False):
        return sp.identity(z.size, format="csr")


def test_newton_stops_early_when_the_gradient_sits_at_its_round_off_floor():
    result = solver.newton(NoisyBowl(), np.ones(3), tolerance=1e-12, max_iterations=100)
    assert not result.success and result.message.startswith("stagnated")
    assert result.iterations <= 2 * solver.STAGNATION_WINDOW + 2
    converged = solver.newton(NoisyBowl(), np.ones(3), tolerance=1e-8, max_iterations=100)
    assert converged.success                                     # a reachable tolerance is unaffected


class _Model:
    """The part of a ForwardModel that :func:`breastcore.forward.model._settle` reads."""

    def __init__(self, method):
        from breastcore.forward.options import SolverOptions
        self.options = SolverOptions(method=method)


@pytest.mark.parametrize("method", ["newton", "cg"])
def test_a_solve_that_ends_on_a_saddle_leaves_it_by_its_own_method(method):
    """Started on the saddle, both minimisers stop at once (g = 0) and report no inertia of their
    own at that point; the inertia at the returned point is computed, and the saddle is left."""
    from breastcore.forward.continuation import _settle
    from breastcore.nonlinear.cg import conjugate_gradient
    problem = DoubleWell()
    on_saddle = (conjugate_gradient(problem, np.zeros(2), 1e-12) if method == "cg"
                 else solver.newton(problem, np.zeros(2), 1e-12))
    assert on_saddle.success and on_saddle.iterations == 0 and not on_saddle.inertia_at_x
    settled = _settle(_Model(method), problem, on_saddle)
    assert settled.success and settled.inertia_at_x and settled.negative_pivots == 0
    assert abs(abs(settled.x[1]) - 2 ** -0.5) < 1e-6 and settled.energy == pytest.approx(-0.25, abs=1e-10)


def test_newton_says_its_inertia_is_that_of_the_iterate_before_its_last_step():
    result = solver.newton(DoubleWell(), np.array([0.3, 0.8]), 1e-12)
    assert result.success and result.iterations > 0 and not result.inertia_at_x


@pytest.fixture(scope="module")
def coarse_model():
    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    return ForwardModel(mesh_level("coarse"))


@pytest.mark.parametrize("method", ["newton", "cg"])
def test_recorded_negative_eigenvalues_are_the_inertia_at_the_returned_position(method):
    """Cold and warm (no iteration needed) solves, Newton and CG: the recorded count is recomputed
    independently at the returned position. CG solves and warm solves used to record -1."""
    from breastcore.forward.model import ForwardModel
    from breastcore.forward.options import SolverOptions
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    from breastcore.model.postures import paper_postures
    model = ForwardModel(mesh_level("coarse"), SolverOptions(method=method))
    params = Parameters()
    for posture in paper_postures():
        cold = model.solve(params, posture)
        warm = model.solve(params, posture, start=cold.position)
        assert warm.iterations == 0
        for solution in (cold, warm):
            problem = model.problem(params, posture)
            inertia = factorization.Factorization(problem.hessian(problem.free(solution.position))).negative_pivots
            assert solution.negative_eigenvalues == inertia == 0
