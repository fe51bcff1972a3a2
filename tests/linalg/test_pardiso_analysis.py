"""PARDISO's symbolic analysis done ahead of the factorisation, and inherited by forked workers."""

import os

import numpy as np
import pytest
from deformations import deformed

from breastcore.fem.assembly import FreeDofAssembler
from breastcore.fem.terms import BulkNeoHookean
from breastcore.forward.model import ForwardModel
from breastcore.linalg import pardiso
from breastcore.linalg.factorization import Factorization, analyse, shift_diagonal
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures

pytestmark = pytest.mark.skipif(not pardiso.available(), reason="the analysis is PARDISO's")


def _indefinite_box_system(small_box, rng):
    """A deformed box's bulk Hessian shifted down to a few negative eigenvalues, its assembler, a right-hand side."""
    nodes, tets, top, bottom = small_box
    free = np.ones(nodes.shape, bool)
    free[bottom.ravel()] = False
    assembler = FreeDofAssembler([tets], free)
    K = assembler.assemble_terms([BulkNeoHookean(nodes, tets, 1000.0, 150.0)], deformed(nodes, rng))
    lowest = np.linalg.eigvalsh(K.toarray())[:4]
    return shift_diagonal(K, -0.5 * (lowest[2] + lowest[3])), assembler, rng.standard_normal(K.shape[0])


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


def _worker_pid(posture, solution):
    return {"jacobian_rows": (os.getpid(),)}                         # any field will do: proves the fork


def test_forked_workers_inherit_the_posture_analyses_and_redo_none(monkeypatch):
    _forbid_analysis_in_children(monkeypatch)
    model = ForwardModel(mesh_level("coarse"))
    solved = model.solve_postures(Parameters(), paper_postures(), processes=2, finish=_worker_pid)
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
