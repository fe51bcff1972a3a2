"""Stability of the forward solve over the issue #2 parameter grid (coarse mesh).

Every case must either return a solution that an independent check accepts
(free-dof gradient recomputed with a fresh model ≤ tolerance, finite, fixed dofs
in place, no inverted tet) or raise ``SolveError``: never NaN, never an
unconverged return, never another exception. The fast test runs the paper's Λ̄
with one factor changed at a time (42 cases); the slow one runs the
``python -m breastcore.studies.stability_grid --quick`` sample (185 cases) in worker processes with a time
cap. The full grid is ``python -m breastcore.studies.stability_grid``.

Also here: the robustness and speed measures of the solver (shared PARDISO
analysis, parallel postures, picklable errors, warm starts rescaled onto a moved
fold) keep results correct.
"""

from collections import Counter

import pytest

from breastcore.studies import stability_grid as grid

ALLOWED = {"converged", "solve_error"}


def _check(rows):
    counts = Counter(r["outcome"] for r in rows)
    bad = [r for r in rows if r["outcome"] not in ALLOWED]
    assert not bad, (counts, [(r["outcome"], r.get("message")) for r in bad[:5]])
    return counts


def test_one_at_a_time_from_paper_values():
    cases = grid.one_at_a_time()
    assert len(cases) == 42
    rows = [grid.run_case(case) for case in cases]
    counts = _check(rows)
    # the paper's own parameters converge in every posture
    paper = [r for r in rows if all(r[k] == v for k, v in grid.PAPER.items() if k != "posture")]
    assert len(paper) == 3 and all(r["outcome"] == "converged" for r in paper)
    assert counts["converged"] >= 40


def test_grid_sampling_covers_every_value():
    cases = grid.sampled_grid(150)
    for name, values in grid.FACTORS.items():
        seen = Counter(c[name] for c in cases)
        assert set(seen) == set(values)
        assert min(seen.values()) >= 0.9 * 150 / len(values)      # (duplicates are dropped)
    assert len(grid.full_grid()) == 4 * 3 * 4 * 3 * 3 * 2 * 3


def test_verify_rejects_an_unconverged_state():
    from breastcore.model.postures import parse_posture
    params = grid.parameters(grid.PAPER)
    model = grid._model("coarse")
    x = model.reference(params.R, params.H)                  # gravity acts: far from equilibrium
    ok, g_norm, tol, _, why = grid.verify("coarse", params, parse_posture("standing"), x)
    assert not ok and g_norm > tol and "gradient" in why


@pytest.mark.slow
def test_sampled_grid_in_worker_processes():
    rows = grid.run_all(grid.sampled_grid(150), processes=2, timeout=300, progress=False)
    counts = _check(rows)
    assert counts["converged"] >= 0.95 * len(rows)


def test_factorisations_sharing_a_pattern_stay_correct():
    """The PARDISO handle of a pattern holds one numeric factor; an older factor refactorises."""
    import numpy as np

    from breastcore.linalg.factorization import Factorization
    from breastcore.model.postures import parse_posture
    model = grid._model("coarse")
    params = grid.parameters(grid.PAPER)
    problem = model.problem(params, parse_posture("bent45"))
    z0 = problem.free(problem.reference)
    K1 = problem.hessian(z0)
    K2 = problem.hessian(z0 + 1e-4 * np.sin(np.arange(z0.size)))
    b = np.cos(np.arange(z0.size))
    # double precision: refinement would hide a solve with the wrong numeric factor
    f1 = Factorization(K1, problem.pattern, mixed=False)
    f2 = Factorization(K2, problem.pattern, mixed=False)     # takes the shared handle
    for K, f in ((K1, f1), (K2, f2), (K1, f1)):
        x = f.solve(b)
        assert np.linalg.norm(K @ x - b) <= 1e-9 * np.linalg.norm(b)
    private = Factorization(K1, mixed=False)                 # its own handle
    assert np.allclose(private.solve(b), f1.solve(b), rtol=1e-10, atol=0)


def test_parallel_postures_give_identical_results():
    import numpy as np

    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    from breastcore.model.postures import paper_postures
    mesh = mesh_level("coarse")
    serial = ForwardModel(mesh).solve_postures(Parameters(), paper_postures())
    parallel = ForwardModel(mesh).solve_postures(Parameters(), paper_postures(), processes=2)
    for a, b in zip(serial, parallel):
        assert a.posture == b.posture and a.iterations == b.iterations
        assert np.array_equal(a.position, b.position)


def test_solve_error_survives_pickling():
    import pickle

    from breastcore.forward.records import SolveError
    err = SolveError("continuation stalled", iterations=3, gradient_norm=1.0, tolerance=1e-9, min_det_F=0.5,
                     load_factor=0.25, smoothing=1e-4, posture="fours")
    back = pickle.loads(pickle.dumps(err))
    assert str(back) == str(err) and back.load_factor == 0.25 and back.posture == "fours"


def test_warm_start_after_changing_all_six_parameters_is_short():
    """The start is rescaled onto the new fold (R, H move it): a few Newton steps, one continuation step.

    Counted in exact Newton steps (``reuse_factor`` 0): chord steps are more and cheaper, and
    would measure the chord rule, not the start."""
    from breastcore.forward.model import ForwardModel
    from breastcore.forward.options import SolverOptions
    from breastcore.model.parameters import Parameters
    from breastcore.model.postures import paper_postures
    model = ForwardModel(grid._model("coarse").mesh, SolverOptions(reuse_factor=0.0))
    params = Parameters()
    changed = params.with_identified([v * 1.01 for v in params.identified()])
    for posture in paper_postures():
        start = model.solve(params, posture).position
        warm = model.solve(changed, posture, start=start)
        assert warm.continuation_steps == 1 and warm.iterations <= 6, (posture.name, warm.iterations)


def test_grid_workers_forked_from_a_two_thread_pardiso_finish():
    """``BREASTCORE_PARDISO_THREADS=2``, and the parent factorised before forking: a worker's factorisation
    on 2 threads hung for ever (GNU OpenMP's threads are not copied by fork), so every case timed out.
    Workers now run PARDISO on one thread. In a fresh interpreter, whose MKL has not been loaded yet."""
    import os
    import textwrap

    from subprocesses import run_script

    from breastcore.linalg import pardiso
    if not pardiso.available():
        pytest.skip("PARDISO (MKL) not installed")
    script = textwrap.dedent("""
        from breastcore.linalg.factorization import Factorization
        from breastcore.model.postures import parse_posture
        from breastcore.studies import stability_grid as grid

        problem = grid._model("coarse").problem(grid.parameters(grid.PAPER), parse_posture("bent45"))
        Factorization(problem.hessian(problem.free(problem.reference)), problem.pattern)   # MKL's threads start
        cases = grid.sampled_grid(2)[:2]
        rows = grid.run_all(cases, processes=2, timeout=30, progress=False)
        print(" ".join(row["outcome"] for row in rows))
    """)
    code, out, err = run_script(script, dict(os.environ, **{pardiso.PARDISO_THREADS_ENV: "2"}), timeout=120)
    assert code == 0, err
    assert out.split() == ["converged", "converged"]
