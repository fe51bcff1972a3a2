"""The forward model's per-(R, H) geometry cache: problems built from it equal fresh builds
bit for bit, whatever the order of visits and evictions, and nothing can write into it."""

import numpy as np
import pytest

import breastcore.forward.model as forward_model
from breastcore.fem.terms import BulkNeoHookean, Chassaignac, Composite, Gravity, SkinMembrane
from breastcore.forward.model import ForwardModel
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures


@pytest.fixture(scope="module")
def coarse():
    return mesh_level("coarse")


def fresh_energy(model, params, acceleration, smoothing):
    """``J_h`` built term by term from the constructors, as before the cache."""
    ref = model.map.positions(params.R, params.H)
    mesh = model.mesh
    return Composite([
        BulkNeoHookean(ref, mesh.tets, params.lambda_breast, params.mu_breast),
        SkinMembrane(ref, mesh.skin_triangles, params.lambda_skin, params.mu_skin, params.skin_thickness),
        Gravity(ref, mesh.tets, params.density, acceleration),
        Chassaignac(ref, mesh.back_triangles, params.chassaignac, smoothing),
    ])


# (R, H) revisited with other moduli, density, coefficient, load and δ, so that every
# template is reused with values other than those it was built with
VISITS = [
    (dict(), 1.0, 1e-4),
    (dict(R=0.06, H=0.045), 0.5, 1e-5),
    (dict(lambda_breast=2000.0, mu_breast=90.0, lambda_skin=1.0e4, mu_skin=900.0, skin_thickness=2e-3), 1.0, 1e-6),
    (dict(density=1100.0, chassaignac=800.0), 0.25, 1e-4),
    (dict(R=0.06, H=0.045, chassaignac=300.0), 1.0, 1e-6),
]


@pytest.mark.parametrize("cache_bytes", [forward_model.GEOMETRY_CACHE_BYTES, 0])
def test_problems_from_the_cache_equal_fresh_builds_bit_for_bit(coarse, monkeypatch, rng, cache_bytes):
    monkeypatch.setattr(forward_model, "GEOMETRY_CACHE_BYTES", cache_bytes)   # 0: only the newest is kept
    monkeypatch.setattr(forward_model, "GEOMETRY_CACHE_ENTRIES", 8)
    model = ForwardModel(coarse)
    posture = paper_postures()[1]
    for changes, load, delta in VISITS + VISITS[::-1]:
        params = Parameters().replace(**changes)
        problem = model.problem(params, posture, load, delta)
        fresh = fresh_energy(model, params, load * posture.gravity(params.gravity_magnitude), delta)
        x = problem.reference + 1e-3 * rng.standard_normal(problem.reference.shape)
        z = problem.free(x)
        assert problem.value(z) == fresh.value(problem.full(z))
        assert np.array_equal(problem.gradient(z), problem.free(fresh.gradient(problem.full(z))))
        K = problem.hessian(z)
        K_fresh = problem.assembler.assemble_terms(fresh.nonlinear_terms, problem.full(z), False)
        assert (K != K_fresh).nnz == 0
    kept = len(model._geometries)
    assert kept == (1 if cache_bytes == 0 else 2)


def test_cached_reference_is_read_only_and_templates_keep_their_values(coarse):
    model = ForwardModel(coarse)
    params = Parameters()
    reference = model.reference(params.R, params.H)
    with pytest.raises(ValueError, match="read-only"):
        reference[0, 0] = 1.0
    model.problem(params.replace(lambda_breast=1234.0, mu_skin=777.0), paper_postures()[0], 0.5, 1e-5)
    geometry = model._geometry(params.R, params.H)
    assert geometry["bulk"].lam == geometry["bulk"].mu == 0.0
    assert geometry["skin"].lam == geometry["skin"].mu == 0.0 and geometry["skin"].thickness == 1.0
    assert np.all(geometry["gravity"][params.density].load == 0.0)


def test_the_cache_keeps_the_newest_entries_within_its_count(coarse, monkeypatch):
    monkeypatch.setattr(forward_model, "GEOMETRY_CACHE_ENTRIES", 3)
    model = ForwardModel(coarse)
    radii = [0.050 + 0.001 * i for i in range(6)]
    for R in radii:
        model.reference(R, 0.04)
    assert list(model._geometries) == [(R, 0.04) for R in radii[-3:]]
    model.reference(radii[3], 0.04)                       # a hit moves it to the newest place
    assert list(model._geometries)[-1] == (radii[3], 0.04) and len(model._geometries) == 3
