"""The cost of computing the inertia at the returned equilibrium (every solve, Newton and CG).

Usage::

    python benchmarks/bench_inertia.py [--levels coarse,medium-thin,ultra-thin] [--repeats 3]
    python benchmarks/bench_inertia.py --quick     # coarse and medium, medians of 3 (``make bench``)

Each cold solve of the paper's Λ̄, per posture and level, is timed twice in one run:
``checked``, the solver as it is (:func:`breastcore.forward.model._settle` factorises the exact
Hessian at the returned position unless the saddle escape did); and ``unchecked``, with
that factorisation replaced by Newton's own inertia from the iterate before its last step
(what solves recorded before 2026-12-01). Medians of ``--repeats``; the ratio is what the
check costs. Both variants return the same equilibrium wherever that last inertia was
right, which the table also checks.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from unittest import mock

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table, timed  # noqa: E402

from breastcore.forward import continuation  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", default=None, help="comma-separated (default coarse,medium-thin,ultra-thin; "
                                                       "--quick: coarse,medium)")
    parser.add_argument("--repeats", type=int, default=3, help="medians of (default 3)")
    parser.add_argument("--quick", action="store_true", help="coarse and medium only (make bench)")
    args = parser.parse_args(argv)
    if args.levels is None:
        args.levels = "coarse,medium" if args.quick else "coarse,medium-thin,ultra-thin"
    return args


def main(argv=None):
    args = parse_args(argv)
    header("Inertia at the returned equilibrium", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    rows = []
    stale = lambda problem, z: None                               # noqa: E731 — Newton's own count is kept
    for level in args.levels.split(","):
        model = ForwardModel(mesh_level(level))
        for posture in paper_postures():
            checked, _, a = timed(lambda: model.solve(Parameters(), posture), args.repeats)
            with mock.patch.object(continuation, "hessian_inertia", stale):
                unchecked, _, b = timed(lambda: model.solve(Parameters(), posture), args.repeats)
            rows.append([level, posture.name, f"{checked:.3f}", f"{unchecked:.3f}", f"{checked / unchecked:.3f}",
                         a.negative_eigenvalues, bool(np.array_equal(a.position, b.position))])
    print_table(["level", "posture", "checked s", "unchecked s", "ratio", "negative eigenvalues", "same equilibrium"],
                rows)


if __name__ == "__main__":
    main()
