"""Mixed-precision factorisation: refinement to double accuracy, and its fallback."""

import numpy as np
import pytest
import scipy.sparse as sp
from deformations import deformed

from breastcore.fem.assembly import FreeDofAssembler
from breastcore.fem.terms import BulkNeoHookean
from breastcore.forward.model import ForwardModel
from breastcore.linalg import factorization, pardiso
from breastcore.linalg.factorization import Factorization
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import parse_posture
from breastcore.nonlinear.newton import newton

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="mixed precision needs PARDISO")


def _relative_residual(K, x, b):
    return np.linalg.norm(b - K @ x) / np.linalg.norm(b)


def test_mixed_precision_solve_is_refined_to_double_accuracy(small_box, rng):
    nodes, tets, top, bottom = small_box
    bulk = BulkNeoHookean(nodes, tets, 1000.0, 150.0)
    free = np.ones(nodes.shape, bool)
    free[bottom.ravel()] = False
    assembler = FreeDofAssembler([tets], free)
    K = assembler.assemble_terms([bulk], deformed(nodes, rng))
    b = rng.standard_normal(K.shape[0])
    double = Factorization(K, assembler.pattern, mixed=False)
    mixed = Factorization(K, assembler.pattern, mixed=True)
    x = mixed.solve(b)
    assert mixed.mixed and mixed.refinement_steps >= 1            # the single factor alone is not enough
    assert _relative_residual(K, x, b) <= factorization.REFINEMENT_RTOL
    np.testing.assert_allclose(x, double.solve(b), rtol=0, atol=1e-10 * np.abs(x).max())
    assert mixed.negative_pivots == double.negative_pivots
    B = rng.standard_normal((K.shape[0], 3))                       # several right-hand sides at once
    assert _relative_residual(K, mixed.solve(B), B) <= np.sqrt(3) * factorization.REFINEMENT_RTOL


def test_ill_conditioned_matrix_falls_back_to_double_precision(rng):
    n = 400                                                        # Neumann Laplacian + 1e-10 I: κ ≈ 4e10
    K = sp.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="lil")
    K[0, 0] = K[n - 1, n - 1] = 1.0
    K = (K + 1e-10 * sp.eye(n)).tocsr()
    K.sort_indices()
    b = rng.standard_normal(n)
    f = Factorization(K, mixed=True)
    x = f.solve(b)
    assert not f.mixed                                             # refinement stalled: refactorised
    assert _relative_residual(K, x, b) <= 1e-6
    x_double = Factorization(K, mixed=False).solve(b)
    np.testing.assert_allclose(x, x_double, rtol=1e-12, atol=0)


def test_newton_in_mixed_precision_reaches_the_same_equilibrium(monkeypatch):
    model, params, fours = ForwardModel(mesh_level("coarse")), Parameters(), parse_posture("fours")
    problem = model.problem(params, fours, 1.0, 1e-4)
    tolerance = model.tolerance(params, fours)
    z0 = problem.free(problem.reference)
    double = newton(problem, z0, tolerance)
    monkeypatch.setattr(factorization, "MIXED_PRECISION_MIN_DOFS", 0)
    assert Factorization(problem.hessian(z0), problem.pattern).mixed                  # the path under test
    mixed = newton(problem, z0, tolerance)
    assert double.success and mixed.success
    assert mixed.negative_pivots == double.negative_pivots == 0
    assert np.linalg.norm(problem.gradient(mixed.x)) <= tolerance           # an equilibrium, recomputed
    np.testing.assert_allclose(mixed.x, double.x, rtol=0, atol=1e-6 * params.R)
