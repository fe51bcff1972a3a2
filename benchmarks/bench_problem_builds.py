"""Identification with and without the forward model's (R, H) geometry cache (issue #21).

Usage::

    python benchmarks/bench_problem_builds.py [--levels coarse,medium,ultra-thin] [--repeats 3]
    python benchmarks/bench_problem_builds.py --quick     # coarse, 1 repeat (``make bench``)

Each level: inverse-crime data (truth on the identification level), the three fixed
starts 30 % off of ``_ident.STARTS_30``, ``lm`` + ``implicit``, one process. Each start
is identified with the cache (``cached``: today's method) and without it
(``uncached``: every problem builds its four terms from their constructors and
``tolerance`` a gravity term, the code before the cache, patched in), alternately in
the same process, ``--repeats`` times; the table gives the medians over starts and
repeats, the ratio of the medians, the problems that built reference arrays in one
identification (the last start) and whether the two estimates are equal bit for bit.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table  # noqa: E402
from benchmarks._ident import STARTS_30, TRUTH, measurement_model, options, truth_measurements  # noqa: E402
from breastcore.fem.terms import BulkNeoHookean, Chassaignac, Gravity, SkinMembrane  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.inverse.identify import identify  # noqa: E402

def _rebuilt_terms(model, params, acceleration, smoothing):
    """The four terms built from their constructors, as every problem did before the cache."""
    reference, mesh = model.map.positions(params.R, params.H), model.mesh
    return (BulkNeoHookean(reference, mesh.tets, params.lambda_breast, params.mu_breast),
            SkinMembrane(reference, mesh.skin_triangles, params.lambda_skin, params.mu_skin, params.skin_thickness),
            Gravity(reference, mesh.tets, params.density, acceleration),
            Chassaignac(reference, mesh.back_triangles, params.chassaignac, smoothing))


def _rebuilt_tolerance(model, params, posture):
    """``ForwardModel.tolerance`` before the cache: a gravity term built for its load norm."""
    load = np.linalg.norm(Gravity(model.map.positions(params.R, params.H), model.mesh.tets, params.density,
                                  posture.gravity(params.gravity_magnitude)).load)
    return model.options.rtol * (load if load > 0 else params.mu_breast * params.R**2)


def identify_once(level, target, start, cached):
    """Seconds, estimate and term builds (problems that built reference arrays) of one identification."""
    builds = [0]
    originals = {name: getattr(ForwardModel, name) for name in ("energy_terms", "reference", "tolerance")}

    def counted(model, params, acceleration, smoothing):
        key = (float(params.R), float(params.H))
        builds[0] += (not cached) or key not in model._geometries
        if cached:
            return originals["energy_terms"](model, params, acceleration, smoothing)
        return _rebuilt_terms(model, params, acceleration, smoothing)

    ForwardModel.energy_terms = counted
    if not cached:
        ForwardModel.reference = lambda model, R, H: model.map.positions(R, H)
        ForwardModel.tolerance = _rebuilt_tolerance
    try:
        mm = measurement_model(level)
        mm.model._geometries.clear()                       # the level's model is shared between runs
        tic = time.perf_counter()
        result = identify(mm, target, start, options())
        return time.perf_counter() - tic, np.asarray(result.estimate), builds[0]
    finally:
        for name, method in originals.items():
            setattr(ForwardModel, name, method)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--levels", default=None,
                        help="comma-separated (default coarse,medium,ultra-thin; --quick: coarse)")
    parser.add_argument("--repeats", type=int, default=None, help="runs per start and variant (default 3; --quick: 1)")
    parser.add_argument("--quick", action="store_true", help="coarse, one repeat (make bench)")
    args = parser.parse_args(argv)
    args.levels = (args.levels or ("coarse" if args.quick else "coarse,medium,ultra-thin")).split(",")
    args.repeats = args.repeats or (1 if args.quick else 3)
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_problem_builds", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    rows = []
    for level in args.levels:
        target = truth_measurements(level)                  # also compiles the kernels
        times = {True: [], False: []}
        builds, equal = {}, True
        for _ in range(args.repeats):
            for factors in STARTS_30:
                start = TRUTH * np.array(factors)
                estimates = {}
                for cached in (False, True):
                    seconds, estimates[cached], builds[cached] = identify_once(level, target, start, cached)
                    times[cached].append(seconds)
                equal &= bool(np.array_equal(estimates[True], estimates[False]))
        uncached, cached = statistics.median(times[False]), statistics.median(times[True])
        rows.append([level, f"{uncached:.2f}", f"{cached:.2f}", f"{cached / uncached:.2f}", str(builds[False]),
                     str(builds[True]), "yes" if equal else "NO"])
    print_table(["level", "uncached (s)", "cached (s)", "cached / uncached", "builds uncached", "builds cached",
                 "same estimate"], rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
