"""How the 15 measurements depend on the Chassaignac smoothing length δ, as spec §2 asks the docs to say.

The sliding term ``c Σ |T|/3 (sqrt(|u|² + δ²) − δ)`` is Tresca friction smoothed on the
length δ: a back node that sticks moves by about ``δ f / c`` under a tangential stress ``f``
below ``c``. This study solves the three paper postures cold at Λ̄ on each mesh level for each
δ, and prints the largest relative difference of the 15 measurements (``paper15``) at each δ
from those at the next smaller δ of the list, per level, with the slope of ``log difference``
against ``log δ``. For ``M(δ) = M(0) (1 + a δ)`` and δ falling by decades, the differences fall
tenfold per decade (slope 1), and the difference between δ and δ/10 is, to first order in aδ,
0.9 × the error of δ itself against the ``δ → 0`` limit. The slope is the order of the
dependence only for δ in a geometric sequence (the default, by decades).

Usage::

    python -m breastcore.studies.smoothing_dependence [--levels coarse medium thin ultra-thin]
                                                      [--deltas 1e-4 1e-5 1e-6 1e-7]
    python -m breastcore.studies.smoothing_dependence --quick    # coarse only

Every solve is a cold solve of the workflow's solver: the gravity ramp at ``smoothing_start``
(default 1e-6 m), then δ lowered by continuation where the target is smaller (δ = 1e-7 m);
at δ ≥ ``smoothing_start`` there is no δ phase. (The figures in docs/benchmarks.md were
measured with ``smoothing_start`` = 1e-4 m, the default then.)
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from breastcore.report.text_table import fmt, header, print_table
from breastcore.studies.mesh_convergence import fit_exponent

LEVELS = ["coarse", "medium", "thin", "ultra-thin"]
DELTAS = [1e-4, 1e-5, 1e-6, 1e-7]


def measurements(model, params, postures):
    """The ``paper15`` measurements of the cold equilibria at ``params``, and the solve time.

    Parameters
    ----------
    model : ForwardModel
    params : Parameters
    postures : sequence of Posture

    Returns
    -------
    values : (5 × len(postures),) array
        Posture by posture, in SI units (m³, m², m).
    seconds : float
        Wall time of the solves, s.
    """
    from breastcore.inverse.operator import MeasurementModel
    mm = MeasurementModel(model, params, postures)
    tic = time.perf_counter()
    values = mm.measure(mm.solve(params.identified())).ravel()
    return values, time.perf_counter() - tic


def differences(by_delta):
    """``{δ: max_i |M_i(δ)/M_i(δ') − 1|}``, δ' the next smaller δ, for every δ but the smallest; and the slope.

    Parameters
    ----------
    by_delta : dict of float → (n,) array
        Measurements per δ (m).

    Returns
    -------
    diff : dict of float → float
        The largest relative difference (1) of each δ from the next smaller one.
    slope : float
        Least-squares slope of ``log diff`` against ``log δ``, over the positive differences
        (NaN with fewer than two).
    """
    deltas = sorted(by_delta)
    diff = {d: float(np.max(np.abs(by_delta[d] / by_delta[smaller] - 1.0))) for smaller, d in zip(deltas, deltas[1:])}
    return diff, fit_exponent(list(diff), list(diff.values())) if len(diff) >= 2 else float("nan")


def parse_args(argv=None):
    """The command line (``sys.argv[1:]`` if ``argv`` is None), with the defaults ``--quick`` implies."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--levels", nargs="+", default=None, help=f"mesh levels (default {' '.join(LEVELS)})")
    parser.add_argument("--deltas", nargs="+", type=float, default=DELTAS, help="smoothing lengths δ, m")
    parser.add_argument("--quick", action="store_true", help="the coarse level only")
    args = parser.parse_args(argv)
    args.levels = args.levels or (["coarse"] if args.quick else LEVELS)
    args.deltas = sorted(set(args.deltas), reverse=True)
    if len(args.deltas) < 2 or min(args.deltas) <= 0:
        parser.error("give at least two different smoothing lengths, all > 0")
    return args


def main(argv=None):
    """Print the table of differences, slopes and solve times per level."""
    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    from breastcore.model.postures import paper_postures
    args = parse_args(argv)
    header("Smoothing dependence", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    deltas = args.deltas
    rows = []
    for level in args.levels:
        model = ForwardModel(mesh_level(level))
        by_delta, seconds = {}, {}
        for delta in deltas:
            by_delta[delta], seconds[delta] = measurements(model, Parameters(smoothing=delta), paper_postures())
        diff, slope = differences(by_delta)
        rows.append([level, len(model.mesh.nodes)] + [fmt(diff[d]) for d in deltas[:-1]] + [fmt(slope)]
                    + [f"{seconds[d]:.1f}" for d in deltas])
    print_table(["level", "nodes"] + [f"δ = {d:g} m vs {e:g} m" for d, e in zip(deltas, deltas[1:])] + ["slope"]
                + [f"solve s, {d:g}" for d in deltas], rows,
                "Largest relative difference of the 15 measurements at Λ̄ from those at the next smaller δ")


if __name__ == "__main__":
    main()
