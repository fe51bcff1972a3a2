"""Set-up and linear-solve costs of a Newton iteration as the mesh grows: pattern, double and mixed precision.

Usage::

    python benchmarks/bench_factorization.py [--levels ultra-thin reference fine10k fine50k] [--repeats 3]
    python benchmarks/bench_factorization.py --quick     # without fine50k (``make bench``)

For each mesh level, with ``BREASTCORE_PARDISO_THREADS`` as set (the fine50k target
uses 2), medians of ``--repeats``:

- ``pattern``: ``ForwardModel.assembler`` on a new model, i.e. building
  :class:`~breastcore.fem.assembly.FreeDofAssembler` (the free-dof CSR pattern and the
  position of every element-block entry), part of every cold solve;
- ``double``: one PARDISO numeric factorisation and solve in double precision;
- ``mixed``: the single-precision factorisation and a solve refined in double to
  ``‖b − Kx‖ ≤ 1e-10 ‖b‖`` (:class:`~breastcore.linalg.factorization.Factorization` with ``mixed=True``),
  with the refinement steps it took.

``--quick`` leaves out fine50k, unless ``--levels`` is given.

The matrix is the exact Hessian at the gravity-free shape under standing gravity, the
right-hand side its gradient. The forward solver uses mixed precision from
``SolverOptions.mixed_precision_min_dofs`` free dofs on (default 0: every level).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table, timed  # noqa: E402

from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.forward.options import SolverOptions  # noqa: E402
from breastcore.linalg import factorization as solver  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import parse_posture  # noqa: E402


def level_row(level, repeats):
    mesh = mesh_level(level)
    params = Parameters()
    fresh = iter([ForwardModel(mesh) for _ in range(max(1, repeats))])   # each builds its assembler once
    t_pattern, _, _ = timed(lambda: next(fresh).assembler(params.fold_angle), repeats)
    model = ForwardModel(mesh)
    problem = model.problem(params, parse_posture("standing"))
    z = problem.free(problem.reference)
    K, b = problem.hessian(z), problem.gradient(z)

    def solve(mixed):
        f = solver.Factorization(K, problem.pattern, mixed=mixed)
        x = f.solve(b)
        return f, np.linalg.norm(b - K @ x) / np.linalg.norm(b)

    t_double, _, (_, res_double) = timed(lambda: solve(False), repeats)
    t_mixed, _, (f_mixed, res_mixed) = timed(lambda: solve(True), repeats)
    return [level, len(mesh.nodes), K.shape[0], t_pattern, t_double, t_mixed, t_double / t_mixed,
            f_mixed.refinement_steps, "yes" if f_mixed.mixed else "no (fell back)", f"{res_double:.1e}",
            f"{res_mixed:.1e}"]


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    # None marks "not given": --quick replaces the levels only when none were asked for.
    parser.add_argument("--levels", nargs="+", default=None,
                        help="mesh levels (default ultra-thin reference fine10k fine50k; --quick: without fine50k)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="ultra-thin, reference, fine10k (make bench)")
    args = parser.parse_args(argv)
    args.levels = args.levels or ["ultra-thin", "reference", "fine10k"] + ([] if args.quick else ["fine50k"])
    return args


def main(argv=None):
    args = parse_args(argv)
    header("Pattern and factorisation costs", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    print(f"PARDISO threads: {os.environ.get('BREASTCORE_PARDISO_THREADS', '1')}; mixed precision from "
          f"{SolverOptions().mixed_precision_min_dofs:,} dofs in the forward solver (SolverOptions; "
          f"{solver.MIXED_PRECISION_MIN_DOFS:,} for a matrix without a model's pattern)\n", flush=True)
    rows = [level_row(level, args.repeats) for level in args.levels]
    print_table(["level", "nodes", "dofs", "pattern s", "double factor+solve s", "mixed factor+solve s",
                 "double/mixed", "refinement steps", "stayed single", "residual double", "residual mixed"],
                rows, title=f"medians of {args.repeats}")


if __name__ == "__main__":
    main()
