"""One Newton system solved by PARDISO against algebraic-multigrid CG (pyamg), per level (issue #21).

Usage::

    python benchmarks/bench_iterative_solver.py [--levels ultra-thin,fine10k,fine50k] [--repeats 3]
    python benchmarks/bench_iterative_solver.py --quick      # ultra-thin (``make bench``)

Issue #21 asks for cold solves that grow at most as N^1.3 with the node count, and for
fine50k postures in ≤ 60 s; a sparse direct factorisation of a 3-D mesh grows faster
(``bench_cold_factorisations.py``). This measures whether an iterative solver would pay
at the project's mesh sizes. The system is the fours posture's Newton system at the
gravity-free state of Λ̄, ``K d = −g`` with ``K`` the PSD-projected Hessian (the
modified-Newton matrix; at this state the exact one is positive definite too). Direct:
PARDISO's numeric factorisation (after its symbolic analysis) and one solve, on
``BREASTCORE_PARDISO_THREADS`` threads (default 1). Iterative: pyamg's smoothed
aggregation with the six rigid-body modes of the free dofs as near-null space
(symmetric strength, θ = 0, coarsest level ≤ 500 unknowns) as the preconditioner of
CG, to a relative residual of 1e-10. Medians of ``--repeats``. ``setup reused`` is the
lower bound of an iterative Newton step, where one hierarchy serves several steps.
Needs pyamg (``pip install -e ".[bench]"``; ``make`` installs it).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table, timed  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.linalg.factorization import Factorization  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import parse_posture  # noqa: E402

RTOL = 1e-10
MAX_COARSE = 500


def newton_system(level):
    """``(K, −g, free mask, reference)`` of the fours posture at the gravity-free state of Λ̄ on ``level``."""
    model, params = ForwardModel(mesh_level(level)), Parameters()
    problem = model.problem(params, parse_posture("fours"))
    z = problem.free(problem.reference)
    return problem, problem.hessian(z, project=True).tocsr(), -problem.gradient(z)


def rigid_body_modes(problem):
    """The 3 translations and 3 rotations of the reference nodes, restricted to the free dofs, ``(n, 6)``."""
    x, free = problem.reference, problem.assembler.free.reshape(-1, 3)
    modes = []
    for axis in range(3):
        mode = np.zeros_like(x)
        mode[:, axis] = 1.0
        modes.append(mode[free])
    for a, b in ((0, 1), (1, 2), (0, 2)):
        mode = np.zeros_like(x)
        mode[:, a], mode[:, b] = -x[:, b], x[:, a]
        modes.append(mode[free])
    return np.column_stack(modes)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--levels", default=None, help="comma-separated (default ultra-thin,fine10k,fine50k; "
                                                       "--quick: ultra-thin)")
    parser.add_argument("--repeats", type=int, default=3, help="runs per median")
    parser.add_argument("--quick", action="store_true", help="ultra-thin only (make bench)")
    args = parser.parse_args(argv)
    args.levels = (args.levels or ("ultra-thin" if args.quick else "ultra-thin,fine10k,fine50k")).split(",")
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_iterative_solver", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    try:
        import pyamg
    except ImportError:
        print('pyamg is not installed: pip install -e ".[bench]"')
        return 1
    rows = []
    for level in args.levels:
        problem, K, rhs = newton_system(level)
        Factorization(K, problem.pattern)                                 # symbolic analysis, once
        factor_s, _, factor = timed(lambda: Factorization(K, problem.pattern), args.repeats)
        solve_s, _, direct = timed(lambda: factor.solve(rhs), args.repeats)
        modes = rigid_body_modes(problem)
        setup_s, _, hierarchy = timed(lambda: pyamg.smoothed_aggregation_solver(
            K, B=modes, strength=("symmetric", {"theta": 0.0}), max_coarse=MAX_COARSE), args.repeats)
        residuals = []

        def krylov():
            residuals.clear()
            return hierarchy.solve(rhs, tol=RTOL, accel="cg", maxiter=1000, residuals=residuals)

        amg_s, _, iterative = timed(krylov, args.repeats)
        relative = np.linalg.norm(K @ iterative - rhs) / np.linalg.norm(rhs)
        difference = np.linalg.norm(iterative - direct) / np.linalg.norm(direct)
        direct_s = factor_s + solve_s
        rows.append([level, str(K.shape[0]), f"{factor_s:.3f}", f"{solve_s:.3f}", f"{setup_s:.3f}", f"{amg_s:.3f}",
                     str(len(residuals) - 1), f"{relative:.1e}", f"{difference:.1e}",
                     f"{(setup_s + amg_s) / direct_s:.2f}", f"{amg_s / direct_s:.2f}"])
        print(f"  {level}: direct {direct_s:.3f} s, AMG-CG {setup_s:.3f} + {amg_s:.3f} s", flush=True)
    print_table(["level", "free dofs", "factorisation (s)", "direct solve (s)", "AMG setup (s)", "AMG-CG solve (s)",
                 "CG iterations", "AMG-CG residual", "vs direct", "AMG / direct", "setup reused / direct"], rows,
                title=f"K d = −g, fours at the gravity-free state of Λ̄; medians of {args.repeats}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
