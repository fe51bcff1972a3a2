"""What would a skin that wrinkles instead of buckling cost and change? A study for issue #21.

Usage::

    python benchmarks/bench_relaxed_skin.py [--levels ultra-thin,reference,fine10k] [--repeats 3]
                                            [--postures standing,bent45,fours] [--paths]
    python benchmarks/bench_relaxed_skin.py --quick     # coarse and medium, one repeat

Per level and paper posture, cold solves at the paper's Λ̄ with the default solver (as
``bench_newton_floor``), two models alternated (the spec's first in odd-numbered repeats, so with one
repeat it always runs first):

- ``spec``: the spec's neo-Hookean skin membrane, which resists compression;
- ``relaxed``: its tension-field relaxation (:mod:`benchmarks._relaxed_skin`, numpy kernels), in
  which a compressed direction wrinkles at no energy. **Another model**, not the spec's.

Printed per solve: the median time, Newton iterations, PARDISO's numeric factorisations and their
largest negative-pivot count (counted at the handle: ``bench_newton_floor._Counter``), the
factorisation-equivalents (time / one factorisation of the spec model's exact Hessian at its
solution), and, at each model's equilibrium, the share of skin triangles that the relaxed energy
calls wrinkled or slack. A second table gives, per posture, what the relaxation changes: the
largest relative change of the five measurements (and which), and the largest node distance
between the two equilibria. The relaxed kernels are numpy, not compiled, so on small meshes the
time ratio understates the relaxed model; the factorisation counts compare the paths.

A third table (``--paths``, on the first level) asks whether each skin's equilibrium depends on the
path: at five points (Λ̄ and four uniform draws within ±40 %, seed 0, as ``bench_cold_variants``) each
posture is solved cold with the default solver, then along other paths: cold with the solver settings
before issue #21 (``bench_cold_variants.BEFORE``), cold with the gravity ramp at δ = 1e-3 m, and from
each other posture's equilibrium. Printed: how many of these end more than 1 µm (largest node
distance) from the default's equilibrium, the largest such distance, and the lowest energy
difference (J; negative where the other path found a lower minimum).
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import add_cold_solve_arguments, cold_solve_defaults, header, print_table  # noqa: E402
from benchmarks._relaxed_skin import RelaxedSkinMembrane, RelaxedSkinModel  # noqa: E402
from benchmarks.bench_cold_factorisations import factorisation_seconds  # noqa: E402
from benchmarks.bench_newton_floor import _Counter, _counts, _spread, counted_solve  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.forward.options import SolverOptions  # noqa: E402
from breastcore.inverse.measurements import QUANTITIES, measure  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402

MODELS = {"spec": ForwardModel, "relaxed": RelaxedSkinModel}


def skin_state_shares(mesh, params, posture, position):
    """``(wrinkled, slack)`` shares of the skin triangles at ``position``, as the relaxed energy sees them."""
    problem = RelaxedSkinModel(mesh).problem(params, posture)
    skin = next(t for t in problem.energy.terms if isinstance(t, RelaxedSkinMembrane))
    states = skin.states(position)
    return float(np.mean(states == 1)), float(np.mean(states == 0))


def measurement_change(mesh, spec, relaxed):
    """``(largest |M_relaxed / M_spec − 1|, its quantity)`` over the five measurements of one posture."""
    a, b = measure(mesh, spec.position), measure(mesh, relaxed.position)
    changes = {q: abs(b[q] / a[q] - 1) for q in QUANTITIES}
    worst = max(changes, key=changes.get)
    return changes[worst], worst


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_cold_solve_arguments(parser)
    parser.add_argument("--paths", action="store_true", help="also the path-independence table (first level)")
    return cold_solve_defaults(parser.parse_args(argv))


#: Another equilibrium: the largest node distance from the default path's, m.
OTHER_EQUILIBRIUM = 1e-6


def path_variants():
    """``{name: SolverOptions}`` of the cold paths compared with the default's."""
    import dataclasses
    from benchmarks.bench_cold_variants import BEFORE
    before = dataclasses.replace(SolverOptions(), **BEFORE)
    return {"before-21": before, "ramp at δ = 1e-3 m": dataclasses.replace(before, smoothing_start=1e-3)}


def path_rows(mesh):
    """Rows of the path-independence table on ``mesh``: per skin and posture, other paths' outcomes."""
    base = Parameters()
    truth = np.array(base.identified())
    rng = np.random.default_rng(0)
    points = [truth] + [truth * (1 + rng.uniform(-0.4, 0.4, len(truth))) for _ in range(4)]
    rows = []
    for name, model_class in MODELS.items():
        default = model_class(mesh)
        others = {label: model_class(mesh, options) for label, options in path_variants().items()}
        outcomes = {p.name: [] for p in paper_postures()}          # (distance m, ΔE J) per other path
        for values in points:
            params = base.with_identified(values)
            solved = {p.name: default.solve(params, p) for p in paper_postures()}
            for posture in paper_postures():
                reference = solved[posture.name]
                paths = [model.solve(params, posture) for model in others.values()]
                paths += [default.solve(params, posture, solved[other].position)
                          for other in solved if other != posture.name]
                outcomes[posture.name] += [(np.linalg.norm(s.position - reference.position, axis=1).max(),
                                            s.energy - reference.energy) for s in paths]
        rows += [path_row(name, posture, found) for posture, found in outcomes.items()]
    return rows


def path_row(skin, posture, found):
    """One row of the path table from ``found``, the other paths' ``(distance m, ΔE J)`` from the default's."""
    elsewhere = sum(distance > OTHER_EQUILIBRIUM for distance, _ in found)
    return [skin, posture, f"{elsewhere} of {len(found)}", f"{1e3 * max(d for d, _ in found):.3g}",
            f"{min(e for _, e in found):.2e}"]


def main(argv=None):
    args = parse_args(argv)
    header("bench_relaxed_skin", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    params = Parameters()
    ForwardModel(mesh_level("coarse")).solve(params, paper_postures()[0])     # compile the kernels first
    rows, changes = [], []
    with _Counter() as counter:
        for level in args.levels:
            mesh = mesh_level(level)
            for posture in (p for p in paper_postures() if p.name in args.postures):
                runs = {name: [] for name in MODELS}
                for repeat in range(args.repeats):          # alternated, the first model swapped each repeat
                    for name in (list(MODELS) if repeat % 2 == 0 else list(MODELS)[::-1]):
                        runs[name].append(counted_solve(mesh, SolverOptions(), params, posture, counter,
                                                        model_class=MODELS[name]))
                factor = factorisation_seconds(ForwardModel(mesh), params, posture, runs["spec"][0][4].position)
                for name, solves in runs.items():
                    seconds = statistics.median(s[0] for s in solves)
                    wrinkled, slack = skin_state_shares(mesh, params, posture, solves[0][4].position)
                    rows.append([level, str(len(mesh.nodes)), posture.name, name, f"{seconds:.3f}",
                                 _spread([s[1] for s in solves]), _counts([s[2] for s in solves]),
                                 _counts([s[3] for s in solves]), str(solves[0][4].negative_eigenvalues),
                                 f"{seconds / factor:.1f}", f"{100 * wrinkled:.1f}", f"{100 * slack:.1f}"])
                spec, relaxed = runs["spec"][0][4], runs["relaxed"][0][4]
                change, quantity = measurement_change(mesh, spec, relaxed)
                distance = np.linalg.norm(spec.position - relaxed.position, axis=1).max()
                changes.append([level, posture.name, f"{100 * change:.2f}", quantity, f"{1e3 * distance:.2f}"])
    print_table(["level", "nodes", "posture", "skin", "time (s)", "Newton iterations", "factorisations",
                 "largest negative-pivot count", "negative eigenvalues at the solution",
                 "factorisation-equivalents", "wrinkled (% of triangles)", "slack (%)"], rows,
                title=f"Cold solves at Λ̄, median of {args.repeats}, the two skins alternated")
    print_table(["level", "posture", "largest measurement change (%)", "quantity", "largest node distance (mm)"],
                changes, title="What the relaxed skin changes at Λ̄ (relaxed against spec)")
    if args.paths:
        print_table(["skin", "posture", "paths ending elsewhere (> 1 µm)", "largest distance (mm)",
                     "lowest ΔE (J)"], path_rows(mesh_level(args.levels[0])),
                    title=f"Does the equilibrium depend on the path? {args.levels[0]}, five points, "
                          f"other cold paths and starts from the other postures")
    return 0


if __name__ == "__main__":
    sys.exit(main())
