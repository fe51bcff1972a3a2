"""Mixed-precision factorisation: refinement to double accuracy, and its fallback; PARDISO's symbolic analysis
done ahead of the factorisation, and inherited by forked workers."""

import dataclasses
import os

import numpy as np
import pytest
import scipy.sparse as sp
from deformations import deformed

from breastcore.fem.assembly import FreeDofAssembler
from breastcore.fem.terms import BulkNeoHookean
from breastcore.forward.model import ForwardModel
from breastcore.forward.options import SolverOptions
from breastcore.linalg import factorization, pardiso
from breastcore.linalg.factorization import Factorization, analyse, shift_diagonal
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures, parse_posture
from breastcore.nonlinear.newton import newton

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="mixed precision needs PARDISO")


def _relative_residual(K, x, b):
    return np.linalg.norm(b - K @ x) / np.linalg.norm(b)


def _box_system(small_box, rng):
    """A deformed box's bulk Hessian (bottom fixed), its assembler and a random right-hand side."""
    nodes, tets, top, bottom = small_box
    free = np.ones(nodes.shape, bool)
    free[bottom.ravel()] = False
    assembler = FreeDofAssembler([tets], free)
    K = assembler.assemble_terms([BulkNeoHookean(nodes, tets, 1000.0, 150.0)], deformed(nodes, rng))
    return K, assembler, rng.standard_normal(K.shape[0])


def test_mixed_precision_solve_is_refined_to_double_accuracy(small_box, rng):
    K, assembler, b = _box_system(small_box, rng)
    double = Factorization(K, assembler.pattern, mixed=False)
    mixed = Factorization(K, assembler.pattern, mixed=True)
    x = mixed.solve(b)
    assert mixed.mixed and mixed.refinement_steps >= 1            # the single factor alone is not enough
    assert _relative_residual(K, x, b) <= factorization.REFINEMENT_RTOL
    np.testing.assert_allclose(x, double.solve(b), rtol=0, atol=1e-10 * np.abs(x).max())
    assert mixed.negative_pivots == double.negative_pivots
    B = rng.standard_normal((K.shape[0], 3))                       # several right-hand sides at once
    assert _relative_residual(K, mixed.solve(B), B) <= np.sqrt(3) * factorization.REFINEMENT_RTOL


def _ill_conditioned(n=400):
    """A Neumann Laplacian + 1e-10 I (κ ≈ 4e10): single-precision refinement stalls on it."""
    K = sp.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="lil")
    K[0, 0] = K[n - 1, n - 1] = 1.0
    K = (K + 1e-10 * sp.eye(n)).tocsr()
    K.sort_indices()
    return K


def test_ill_conditioned_matrix_falls_back_to_double_precision(rng):
    K = _ill_conditioned()
    b = rng.standard_normal(K.shape[0])
    f = Factorization(K, mixed=True)
    x = f.solve(b)
    assert not f.mixed                                             # refinement stalled: refactorised
    assert _relative_residual(K, x, b) <= 1e-6
    x_double = Factorization(K, mixed=False).solve(b)
    np.testing.assert_allclose(x, x_double, rtol=1e-12, atol=0)


def test_a_pattern_holds_one_numeric_factor_at_a_time_across_precisions(rng):
    K = _ill_conditioned()
    pattern = pardiso.SymmetricPattern(K.indptr, K.indices, K.shape[0])
    b = rng.standard_normal(K.shape[0])
    stalled = Factorization(K, pattern, mixed=True)
    assert pattern.handle(single=True).owner == stalled._token
    x = stalled.solve(b)                                           # stalls: redone in double
    assert not stalled.mixed
    single, double = pattern.handle(single=True), pattern.handle(single=False)
    assert single.owner is None and double.owner == stalled._token  # the single factor was freed
    well = (K + sp.eye(K.shape[0])).tocsr()                       # same pattern, well conditioned
    fresh = Factorization(well, pattern, mixed=True)
    assert single.owner == fresh._token and double.owner is None   # the double factor was freed
    np.testing.assert_array_equal(stalled.solve(b), x)             # a freed factor is redone from its matrix
    assert double.owner == stalled._token and single.owner is None
    y = fresh.solve(b)
    assert _relative_residual(well, y, b) <= factorization.REFINEMENT_RTOL and single.owner == fresh._token
    np.testing.assert_array_equal(Factorization(well, pattern, mixed=True).solve(b), y)


def _solved_with_phases_recorded(box, rng, monkeypatch):
    """A solved double-precision factor of the box system, and the PARDISO phases its handle calls from now on:
    ``(pattern, factor, b, x, handle, phases)``."""
    K, assembler, b = _box_system(box, rng)
    pattern = assembler.pattern
    first = Factorization(K, pattern, mixed=False)
    x = first.solve(b)
    handle = pattern.handle(single=False)
    phases = []
    call = handle._call
    monkeypatch.setattr(handle, "_call", lambda phase, *args, **kw: phases.append(phase) or call(phase, *args, **kw))
    return pattern, first, b, x, handle, phases


def test_freeing_a_factor_calls_phase_0_once_and_keeps_the_symbolic_analysis(small_box, rng, monkeypatch):
    _, first, b, x, handle, phases = _solved_with_phases_recorded(small_box, rng, monkeypatch)
    handle.release_factor()
    handle.release_factor()                                        # a second release is a no-op
    assert phases == [0] and handle.owner is None
    np.testing.assert_array_equal(first.solve(b), x)               # numeric phase and solve only: no new analysis
    assert phases == [0, 22, 33]


def test_a_handle_analysed_on_another_thread_count_is_analysed_again_without_touching_the_old_one(
        small_box, rng, monkeypatch):
    """As in a worker forked from a 2-thread process: the old analysis and factor are forgotten (PARDISO
    segfaults on them), the factor is redone from its matrix, and the solution is the same."""
    pattern, first, b, x, handle, phases = _solved_with_phases_recorded(small_box, rng, monkeypatch)
    monkeypatch.setattr(pardiso._Pardiso, "_threads", handle.threads + 1)   # as one_thread_in_forked_worker does
    assert not handle.holds(first._token) and not handle.analysed and not handle.pt.any()
    with pytest.raises(RuntimeError, match="without a numeric factor"):
        handle.solve(first._data, b)                               # not phase 33 on forgotten memory
    np.testing.assert_allclose(first.solve(b), x, rtol=1e-12)
    assert phases == [11, 22, 33] and handle.threads == pardiso._Pardiso._threads
    pattern.release()                                              # freed on the patched count, not leaked


def test_newton_in_mixed_precision_reaches_the_same_equilibrium():
    params, fours = Parameters(), parse_posture("fours")
    model = ForwardModel(mesh_level("coarse"), SolverOptions(mixed_precision_min_dofs=100_000))
    problem = model.problem(params, fours, 1.0, 1e-4)
    tolerance = model.tolerance(params, fours)
    z0 = problem.free(problem.reference)
    double = newton(problem, z0, tolerance)
    assert not Factorization(problem.hessian(z0), problem.pattern).mixed
    problem = ForwardModel(mesh_level("coarse"), SolverOptions(mixed_precision_min_dofs=0)).problem(params, fours,
                                                                                                   1.0, 1e-4)
    assert Factorization(problem.hessian(z0), problem.pattern).mixed                  # the path under test
    mixed = newton(problem, z0, tolerance)
    assert double.success and mixed.success
    assert mixed.negative_pivots == double.negative_pivots == 0
    assert np.linalg.norm(problem.gradient(mixed.x)) <= tolerance           # an equilibrium, recomputed
    np.testing.assert_allclose(mixed.x, double.x, rtol=0, atol=1e-6 * params.R)


def test_solver_option_sets_the_mixed_precision_threshold_of_the_model_factorisations():
    """``SolverOptions.mixed_precision_min_dofs`` reaches every factorisation on the model's pattern:
    0 puts the coarse level (611 dofs) in single precision, 100,000 keeps it in double."""
    mesh, params, standing = mesh_level("coarse"), Parameters(), parse_posture("standing")
    kinds = {}
    for threshold in (0, 100_000):
        model = ForwardModel(mesh, SolverOptions(mixed_precision_min_dofs=threshold))
        solution = model.solve(params, standing)
        assert solution.gradient_norm <= solution.tolerance                     # converged either way
        kinds[threshold] = model.tangent(params, standing, solution.position)[1].mixed
    assert kinds == {0: True, 100_000: False}


@pytest.mark.parametrize("bad", [-1, 1.5, True])
def test_mixed_precision_threshold_must_be_a_non_negative_integer(bad):
    with pytest.raises(ValueError, match="mixed_precision_min_dofs"):
        SolverOptions(mixed_precision_min_dofs=bad)


def test_a_loose_rtol_stops_the_refinement_as_soon_as_the_residual_meets_it(small_box, rng):
    """``solve(b, rtol)``: an inexact Newton direction needs ‖b − Kx‖ ≤ rtol ‖b‖, not double accuracy."""
    K, assembler, b = _box_system(small_box, rng)
    first = _relative_residual(K, Factorization(K, assembler.pattern, mixed=True)._solve_factor(b), b)
    assert factorization.REFINEMENT_RTOL < first < 1e-3            # single precision alone: between the two
    loose = Factorization(K, assembler.pattern, mixed=True)
    x = loose.solve(b, rtol=1e-3)
    assert loose.refinement_steps == 0 and _relative_residual(K, x, b) <= 1e-3
    strict = Factorization(K, assembler.pattern, mixed=True)
    assert _relative_residual(K, strict.solve(b), b) <= factorization.REFINEMENT_RTOL
    assert strict.refinement_steps >= 1
    tight = Factorization(K, assembler.pattern, mixed=True)
    x = tight.solve(b, rtol=0.1 * first)                           # below the first residual: refined
    assert tight.refinement_steps >= 1 and _relative_residual(K, x, b) <= 0.1 * first


def test_a_failed_numeric_factorisation_is_still_freed(small_box, rng, monkeypatch):
    K, assembler, b = _box_system(small_box, rng)
    pattern = assembler.pattern
    Factorization(K, pattern, mixed=False)
    handle = pattern.handle(single=False)
    phases = []
    call = handle._call

    def failing(phase, *args, **kw):
        phases.append(phase)
        if phase == 22:
            raise RuntimeError("PARDISO phase 22 failed with error -4")
        return call(phase, *args, **kw)
    monkeypatch.setattr(handle, "_call", failing)
    with pytest.raises(RuntimeError):
        handle.factorize(np.ascontiguousarray(K.data[pattern.upper]), owner=-1)
    assert handle.owner is None
    pattern.handle_to_factorize(single=True)                      # the other precision: frees this one
    assert phases == [22, 0]


def _indefinite_box_system(small_box, rng):
    """:func:`_box_system` with its Hessian shifted down to three negative eigenvalues."""
    K, assembler, b = _box_system(small_box, rng)
    lowest = np.linalg.eigvalsh(K.toarray())[:4]
    return shift_diagonal(K, -0.5 * (lowest[2] + lowest[3])), assembler, b


@pytest.mark.parametrize("mixed", [True, False])
def test_an_analysis_on_zeros_gives_the_factors_of_an_analysis_on_the_matrix(small_box, rng, mixed):
    K, assembler, b = _indefinite_box_system(small_box, rng)
    at_factorisation = assembler.pattern.sibling()                    # analysed by its first factorisation
    ahead = assembler.pattern.sibling()
    ahead.analyse(single=mixed)
    assert ahead.handle(single=mixed).analysed and not at_factorisation._handles
    first = Factorization(K, at_factorisation, mixed=mixed)
    second = Factorization(K, ahead, mixed=mixed)
    assert first.negative_pivots == second.negative_pivots == 3
    np.testing.assert_array_equal(second.solve(b), first.solve(b))   # bit for bit
    calls = []
    call = pardiso._Pardiso._call
    ahead.handle(single=mixed)._call = lambda phase, *a, **k: calls.append(phase) or call(ahead.handle(mixed), phase,
                                                                                            *a, **k)
    ahead.analyse(single=mixed)                                       # done already: no PARDISO call
    assert calls == []


def test_analyse_uses_the_precision_of_the_patterns_factorisations():
    model = ForwardModel(mesh_level("coarse"))
    pattern = model.pattern(Parameters().fold_angle, "standing")
    pattern.mixed_min_dofs = pattern.n + 1                            # double precision for this pattern
    analyse(pattern)
    assert pattern.handle(single=False).analysed and True not in pattern._handles
    pattern.mixed_min_dofs = 0
    analyse(pattern)
    assert pattern.handle(single=True).analysed


class AnalysisInWorker(BaseException):
    """Raised by the guard below: a BaseException, so that no solver's error handling swallows it."""


def _forbid_analysis_in_children(monkeypatch):
    """Make a single-precision symbolic analysis in any process but this one raise."""
    parent = os.getpid()
    call = pardiso._Pardiso._call

    def guarded(self, phase, *args, **kwargs):
        if phase == 11 and os.getpid() != parent and self.dtype == np.float32:
            raise AnalysisInWorker("symbolic analysis in a forked worker")
        return call(self, phase, *args, **kwargs)
    monkeypatch.setattr(pardiso._Pardiso, "_call", guarded)


def test_forked_workers_inherit_the_posture_analyses_and_redo_none(monkeypatch):
    _forbid_analysis_in_children(monkeypatch)
    solve = ForwardModel.solve
    monkeypatch.setattr(ForwardModel, "solve", lambda *args: dataclasses.replace(   # any field will do:
        solve(*args), jacobian_rows=(os.getpid(),)))                                 # it proves the fork
    model = ForwardModel(mesh_level("coarse"))
    solved = model.solve_postures(Parameters(), paper_postures(), processes=2)
    assert all(s.jacobian_rows[0] != os.getpid() for s in solved)   # solved in forked workers
    fold = Parameters().fold_angle
    assert all(model.pattern(fold, p.name).handle(single=True).analysed for p in paper_postures())
    # the control: workers that drop the parent's analyses redo them, and the guard catches it
    keep = ForwardModel.after_fork
    monkeypatch.setattr(ForwardModel, "after_fork", lambda self, keep_analyses=False: keep(self, False))
    with pytest.raises(AnalysisInWorker, match="forked worker"):
        ForwardModel(mesh_level("coarse")).solve_postures(Parameters(), paper_postures(), processes=2)


def test_after_fork_drops_the_kept_tangents_and_the_analyses_unless_kept():
    model = ForwardModel(mesh_level("coarse"))
    fold = Parameters().fold_angle
    pattern = model.pattern(fold, "standing")
    model._tangents = {"standing": object()}
    model.after_fork(keep_analyses=True)
    assert model._tangents == {} and model.pattern(fold, "standing") is pattern
    model.after_fork()
    assert model.pattern(fold, "standing") is not pattern
