"""Compile and cache every numba kernel once, at install time.

The element loops of :mod:`breastcore.fem.compiled`, ``compiled_geometry`` and
``compiled_skin`` are compiled on first use and cached beside the module
(``cache=True``). Without a cache, each process of a fresh install compiles them
again, about 3 s each, until one has written the cache; the first workflow jobs, run
side by side, all pay it. ``make`` runs this module after ``pip install``
(``python -m breastcore.fem.warm``), so no job does.

It builds one posture's problem on the coarse mesh (the reference geometry) and evaluates
its energy, gradient, exact Hessian, PSD-projected Hessian and deformation diagnostics,
which is every compiled kernel called with the argument types a solve uses.
"""

from __future__ import annotations

import time


def warm_compiled_kernels() -> float:
    """Call every compiled kernel once with production argument types; return the seconds it took."""
    from breastcore.forward.model import ForwardModel
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    from breastcore.model.postures import paper_postures

    tic = time.perf_counter()
    model = ForwardModel(mesh_level("coarse"))
    params = Parameters()
    problem = model.problem(params, paper_postures()[0])
    z = problem.free(model.reference(params.R, params.H))
    problem.value(z)
    problem.gradient(z)
    problem.hessian(z)
    problem.hessian(z, project=True)
    problem.bulk.deformation_extremes(problem.full(z))
    return time.perf_counter() - tic


if __name__ == "__main__":
    print(f"breastcore: numba kernels compiled and cached in {warm_compiled_kernels():.1f} s")
