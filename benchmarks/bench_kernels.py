"""The compiled skin, reference-geometry and diagnostics loops against the numpy code they replaced (issue #21).

Usage::

    python benchmarks/bench_kernels.py [--levels coarse,ultra-thin,fine10k] [--repeats 20]
                                       [--identify-levels ultra-thin] [--identify-repeats 1]
    python benchmarks/bench_kernels.py --quick     # coarse and ultra-thin kernels, 5 repeats; coarse
                                                   # identifications, 1 repeat (``make bench``)

**Kernels.** Per level, at the cold standing equilibrium at Λ̄: the median time of one call
(over ``--repeats``) of each compiled loop and of its numpy version, in the same process:

- the skin energy (``SkinMembrane.value`` against ``element_energies(x).sum()``);
- the skin gradient (``gradient`` against ``element_gradients`` summed onto the nodes);
- the skin Hessian into the CSR data (``scatter_hessian`` against ``element_hessians`` and
  ``scatter_blocks``, as ``assemble_terms`` did);
- the bulk term's reference arrays (``BulkNeoHookean(...)`` against numpy's batched ``det``
  and ``inv`` and the block constant that the constructor built before);
- the solve's diagnostics (``deformation_extremes`` against ``det`` and ``eigvalsh`` of ``FᵀF``).

**Identifications.** Per ``--identify-levels`` level: inverse-crime data, the three fixed
starts 30 % off of ``_ident.STARTS_30``, ``lm`` + ``implicit``, one process, with the
compiled loops (``compiled``: today's code) and with the numpy versions patched back in
(``numpy``: the code before), alternately in the same process; medians over starts and
repeats, their ratio, and the largest relative difference of the two estimates.
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks._common import header, print_table, timed  # noqa: E402
from benchmarks._ident import STARTS_30, TRUTH, measurement_model, options, truth_measurements  # noqa: E402
from breastcore.fem import compiled, compiled_skin  # noqa: E402
from breastcore.fem.assembly import element_dofs  # noqa: E402
from breastcore.fem.bulk import BulkNeoHookean  # noqa: E402
from breastcore.fem.skin import SkinMembrane  # noqa: E402
from breastcore.forward import continuation  # noqa: E402
from breastcore.forward.model import ForwardModel  # noqa: E402
from breastcore.inverse.identify import identify  # noqa: E402
from breastcore.model.mesh import mesh_level  # noqa: E402
from breastcore.model.parameters import Parameters  # noqa: E402
from breastcore.model.postures import paper_postures  # noqa: E402


def numpy_bulk_reference(reference, tets):
    """The bulk constructor's arrays as numpy built them before the compiled loop (with its block constant)."""
    Dm = np.swapaxes(reference[tets[:, 1:]] - reference[tets[:, :1]], 1, 2)
    volume = np.linalg.det(Dm) / 6.0
    Dm_inv = np.linalg.inv(Dm)
    shape_gradients = np.concatenate([-Dm_inv.sum(axis=1, keepdims=True), Dm_inv], axis=1)
    volume_GG = np.einsum("naj,nbj->nab", shape_gradients, shape_gradients) * volume[:, None, None]
    return volume, shape_gradients, volume_GG


def numpy_diagnostics(problem, x):
    """``(min det F, max stretch)`` as the solve computed them before the compiled loop."""
    F = problem.bulk.deformation_gradient(x)
    return float(np.linalg.det(F).min()), float(np.sqrt(np.linalg.eigvalsh(np.einsum("nki,nkj->nij", F, F)).max()))


def _numpy_skin_gradient(skin, x):
    return np.bincount(element_dofs(skin.connectivity).ravel(), weights=skin.element_gradients(x).ravel(),
                       minlength=x.size).reshape(x.shape)


def kernel_rows(level, repeats):
    """Table rows (kernel, compiled ms, numpy ms, ratio, largest relative difference) on ``level``."""
    params, posture = Parameters(), paper_postures()[0]
    model = ForwardModel(mesh_level(level))
    x = model.solve(params, posture).position
    problem = model.problem(params, posture)
    skin = problem.energy.terms[1]
    positions = problem.assembler.positions[1]
    reference = model.reference(params.R, params.H)

    def skin_hessian(compiled_path):
        data = np.zeros(problem.assembler.nnz)
        if compiled_path:
            skin.scatter_hessian(data, positions, x)
        else:
            compiled.scatter_blocks(data, positions, np.ascontiguousarray(skin.element_hessians(x)))
        return data

    pairs = [
        ("skin energy", lambda: skin.value(x), lambda: skin.element_energies(x).sum()),
        ("skin gradient", lambda: skin.gradient(x), lambda: _numpy_skin_gradient(skin, x)),
        ("skin Hessian into CSR", lambda: skin_hessian(True), lambda: skin_hessian(False)),
        ("bulk reference arrays", lambda: BulkNeoHookean(reference, model.mesh.tets, 0.0, 0.0).shape_gradients,
         lambda: numpy_bulk_reference(reference, model.mesh.tets)[1]),
        ("min det F, max stretch", lambda: np.array(problem.bulk.deformation_extremes(x)),
         lambda: np.array(numpy_diagnostics(problem, x))),
    ]
    rows = []
    for name, fast, slow in pairs:
        fast()                                                      # compiled (cached) before timing
        t_fast, _, a = timed(fast, repeats)
        t_slow, _, b = timed(slow, repeats)
        a, b = np.asarray(a, float), np.asarray(b, float)
        difference = float(np.abs(a - b).max() / np.abs(b).max())
        rows.append([level, name, f"{1e3 * t_fast:.3f}", f"{1e3 * t_slow:.3f}", f"{t_fast / t_slow:.3f}",
                     f"{difference:.1e}"])
    return rows


@contextlib.contextmanager
def numpy_loops():
    """The skin, the bulk constructor and the solve's diagnostics as they were before the compiled loops."""
    saved = {"value": SkinMembrane.value, "checked_value": SkinMembrane.checked_value,
             "gradient": SkinMembrane.gradient, "scatter_hessian": SkinMembrane.scatter_hessian,
             "bulk_init": BulkNeoHookean.__init__, "diagnostics": continuation._diagnostics}

    def checked_value(skin, x):
        ratio = skin.metric_ratio(x)
        degenerate = not np.all(ratio > compiled_skin.DEGENERATE_METRIC_RATIO)
        return np.inf if degenerate else float(skin.element_energies(x).sum())

    def bulk_init(bulk, reference, tets, lam, mu):
        bulk.connectivity = np.asarray(tets)
        bulk.lam, bulk.mu = float(lam), float(mu)
        bulk.volume, bulk.shape_gradients, bulk._volume_GG = numpy_bulk_reference(reference, bulk.connectivity)
        if np.any(bulk.volume <= 0):
            raise ValueError("reference mesh has non-positive tetrahedra")

    SkinMembrane.value = lambda skin, x: float(skin.element_energies(x).sum())
    SkinMembrane.checked_value = checked_value
    SkinMembrane.gradient = _numpy_skin_gradient
    del SkinMembrane.scatter_hessian                                # assemble_terms then scatters the numpy blocks
    BulkNeoHookean.__init__ = bulk_init
    continuation._diagnostics = numpy_diagnostics
    try:
        yield
    finally:
        for name in ("value", "checked_value", "gradient", "scatter_hessian"):
            setattr(SkinMembrane, name, saved[name])
        BulkNeoHookean.__init__ = saved["bulk_init"]
        continuation._diagnostics = saved["diagnostics"]


def identify_once(level, target, start, use_numpy):
    """Seconds and estimate of one identification, with the compiled loops or the numpy ones."""
    mm = measurement_model(level)
    mm.model._geometries.clear()                                    # the level's model is shared between runs
    with numpy_loops() if use_numpy else contextlib.nullcontext():
        tic = time.perf_counter()
        result = identify(mm, target, start, options())
        return time.perf_counter() - tic, np.asarray(result.estimate)


def identification_row(level, repeats):
    target = truth_measurements(level)
    times = {False: [], True: []}
    difference = 0.0
    for _ in range(repeats):
        for i, factors in enumerate(STARTS_30):
            start = TRUTH * np.array(factors)
            estimates = {}
            for use_numpy in ((True, False) if i % 2 == 0 else (False, True)):   # alternate which goes first
                seconds, estimates[use_numpy] = identify_once(level, target, start, use_numpy)
                times[use_numpy].append(seconds)
            difference = max(difference, float(np.max(np.abs(estimates[False] / estimates[True] - 1.0))))
    slow, fast = statistics.median(times[True]), statistics.median(times[False])
    return [level, f"{slow:.2f}", f"{fast:.2f}", f"{fast / slow:.3f}", f"{sum(times[False]) / sum(times[True]):.3f}",
            f"{difference:.1e}"]


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--levels", default=None,
                        help="kernel levels, comma-separated (default coarse,ultra-thin,fine10k; "
                             "--quick: coarse,ultra-thin)")
    parser.add_argument("--repeats", type=int, default=None, help="calls per kernel median (default 20; --quick: 5)")
    parser.add_argument("--identify-levels", default=None,
                        help="identification levels (default ultra-thin; --quick: coarse; 'none' to skip)")
    parser.add_argument("--identify-repeats", type=int, default=1, help="runs per start and variant (default 1)")
    parser.add_argument("--quick", action="store_true", help="smaller levels and samples (make bench)")
    args = parser.parse_args(argv)
    args.levels = (args.levels or ("coarse,ultra-thin" if args.quick else "coarse,ultra-thin,fine10k")).split(",")
    args.repeats = args.repeats or (5 if args.quick else 20)
    identify_levels = args.identify_levels or ("coarse" if args.quick else "ultra-thin")
    args.identify_levels = [] if identify_levels == "none" else identify_levels.split(",")
    return args


def main(argv=None):
    args = parse_args(argv)
    header("bench_kernels", [sys.argv[0]] + (argv if argv is not None else sys.argv[1:]))
    rows = [row for level in args.levels for row in kernel_rows(level, args.repeats)]
    print_table(["level", "kernel", "compiled (ms)", "numpy (ms)", "compiled / numpy", "largest rel. difference"],
                rows, title=f"One call at the standing equilibrium at Λ̄, medians of {args.repeats}")
    if args.identify_levels:
        rows = [identification_row(level, args.identify_repeats) for level in args.identify_levels]
        print_table(["level", "numpy median (s)", "compiled median (s)", "ratio of medians", "ratio of totals",
                     "largest estimate difference"], rows,
                    title=f"Identification from the 3 starts 30 % off, {args.identify_repeats} run(s) per start and "
                          "variant, alternating")
    return 0


if __name__ == "__main__":
    sys.exit(main())
