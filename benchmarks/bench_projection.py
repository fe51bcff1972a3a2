"""The PSD-projected Hessian (modified Newton's step): analytic eigensystem against per-block eigh.

Usage::

    python benchmarks/bench_projection.py [--levels medium,medium-thin,ultra-thin] [--repeats 7]
    python benchmarks/bench_projection.py --quick     # medians of 3 (``make bench``)

For each mesh level, at the cold standing equilibrium of the reference parameters
(``Parameters()``), times the assembly of the free-dof Hessian, medians of ``--repeats``:

- ``exact``: :meth:`EquilibriumProblem.hessian` (compiled bulk scatter);
- ``projected``: ``hessian(project=True)``, the bulk's tangent modulus ∂²W/∂F²
  projected through its analytic eigensystem in a compiled loop, the skin blocks by
  ``eigh`` (what the solver uses since 01f4f21, 2026-11-22);
- ``12×12 eigh``: the method before it, every bulk and skin element block built in
  numpy and projected by a batched ``eigh`` (:func:`breastcore.fem.terms.project_psd`),
  then assembled. Kept here, not in the package, as the baseline.

``--quick`` takes medians of 3 instead of 7, unless ``--repeats`` is given.

Also prints, for scale, one PARDISO numeric factorisation of the exact Hessian, and
the share of tets whose tangent modulus is indefinite there.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table, timed  # noqa: E402

from breastcore.fem.terms import Chassaignac, project_psd  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.linalg.factorization import Factorization  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import parse_posture  # noqa: E402


def eigh_per_block(problem, x):
    """The previous projected Hessian: every non-Chassaignac element block clamped by ``eigh``."""
    blocks = []
    for term in problem.energy.nonlinear_terms:
        H = term.element_hessians(x)
        blocks.append((term.connectivity, H if isinstance(term, Chassaignac) else project_psd(H)))
    return problem.assembler.assemble(blocks)


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", default="medium,medium-thin,ultra-thin")
    parser.add_argument("--repeats", type=int, default=None, help="medians of (default 7; --quick: 3)")
    parser.add_argument("--quick", action="store_true", help="medians of 3 (make bench)")
    args = parser.parse_args(argv)
    if args.repeats is None:
        args.repeats = 3 if args.quick else 7
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_projection", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    rows = []
    for level in args.levels.split(","):
        model = ForwardModel(mesh_level(level))
        params, posture = Parameters(), parse_posture("standing")
        x = model.solve(params, posture).position
        problem = model.problem(params, posture)
        z = problem.free(x)
        exact_s, _, K = timed(lambda: problem.hessian(z), args.repeats)
        projected_s, _, _ = timed(lambda: problem.hessian(z, project=True), args.repeats)
        eigh_s, _, _ = timed(lambda: eigh_per_block(problem, x), args.repeats)
        factor_s, _, _ = timed(lambda: Factorization(K, problem.pattern), args.repeats)
        indefinite = np.linalg.eigvalsh(problem.bulk.tangent_moduli(x)).min(axis=1) < 0
        rows.append([level, len(problem.bulk.connectivity), f"{100 * indefinite.mean():.0f} %",
                     f"{1e3 * exact_s:.1f}", f"{1e3 * projected_s:.1f}", f"{1e3 * eigh_s:.1f}",
                     f"{eigh_s / projected_s:.1f}×", f"{1e3 * factor_s:.1f}"])
    print_table(["level", "tets", "indefinite C", "exact ms", "projected ms", "12×12 eigh ms", "speed-up",
                 "factorisation ms"], rows,
                title=f"Hessian assembly at the cold standing equilibrium, median of {args.repeats}")


if __name__ == "__main__":
    main()
