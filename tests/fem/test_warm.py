"""``python -m breastcore.fem.warm`` (run by ``make`` after install) leaves a numba cache
entry for every compiled kernel, so that no workflow job compiles one."""

import inspect
import os
import subprocess
import sys

from breastcore.fem import compiled, compiled_geometry, compiled_skin


def dispatchers(*modules):
    """The numba dispatchers defined or imported in ``modules``, each once."""
    found = {id(obj): obj for module in modules for obj in vars(module).values()
             if getattr(obj, "py_func", None) is not None and hasattr(obj, "stats")}
    return list(found.values())


def kernel_cache_prefixes():
    """``<module>.<function>-`` of every numba dispatcher in :mod:`breastcore.fem.compiled`,
    :mod:`~breastcore.fem.compiled_geometry` and :mod:`~breastcore.fem.compiled_skin` (numba's file names)."""
    prefixes = set()
    for obj in dispatchers(compiled, compiled_geometry, compiled_skin):
        func = obj.py_func
        prefixes.add(f"{func.__module__.rsplit('.', 1)[-1]}.{func.__qualname__}-")
    return prefixes


def test_warm_caches_every_compiled_kernel(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-m", "breastcore.fem.warm"], env=env, capture_output=True, text=True,
                         timeout=600, check=True)
    assert "numba kernels compiled and cached in" in out.stdout
    written = [p.name for p in tmp_path.rglob("*.nbi")]
    prefixes = kernel_cache_prefixes()
    assert len(prefixes) >= 10                                   # the dispatchers were found at all
    missing = sorted(p for p in prefixes if not any(name.startswith(p) for name in written))
    assert not missing, f"not cached by the warm-up: {missing}"
    # a solve and its final inertia check, as a workflow job runs them, in a new process:
    # every kernel it calls is loaded from that cache, none compiled
    job = subprocess.run([sys.executable, "-c", SOLVE_AND_COUNT], env=env, capture_output=True, text=True,
                         timeout=600, check=True)
    hits, misses = map(int, job.stdout.split())
    assert hits >= 7 and misses == 0, job.stdout             # bulk and skin energy, gradient, Hessian; …


SOLVE_AND_COUNT = inspect.getsource(dispatchers) + """
from breastcore.fem import compiled, compiled_geometry, compiled_skin
from breastcore.forward.model import ForwardModel
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures
ForwardModel(mesh_level("coarse")).solve(Parameters(), paper_postures()[2])
stats = [obj.stats for obj in dispatchers(compiled, compiled_geometry, compiled_skin)]
print(sum(sum(s.cache_hits.values()) for s in stats), sum(sum(s.cache_misses.values()) for s in stats))
"""
