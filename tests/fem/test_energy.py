"""Energy terms: analytic gradients and Hessians against central differences,
zero energy at rest, closed forms under homogeneous stretch, rigid invariance."""

import numpy as np
import pytest

from breastcore.fem.assembly import FreeDofAssembler
from breastcore.fem.terms import BulkNeoHookean, Chassaignac, Composite, Gravity, SkinMembrane, project_psd
from deformations import deformed


def make_terms(nodes, tets, top, bottom, delta=1e-3):
    return [
        BulkNeoHookean(nodes, tets, lam=1000.0, mu=150.0),
        SkinMembrane(nodes, top, lam=8000.0, mu=1600.0, thickness=1e-3),
        Gravity(nodes, tets, density=1000.0, acceleration=[0.0, 6.9, -6.9]),
        Chassaignac(nodes, bottom, coefficient=100.0, smoothing=delta),
    ]


def fd_gradient(f, x, h):
    g = np.zeros(x.size)
    for i in range(x.size):
        xp, xm = x.copy().ravel(), x.copy().ravel()
        xp[i] += h
        xm[i] -= h
        g[i] = (f(xp.reshape(x.shape)) - f(xm.reshape(x.shape))) / (2 * h)
    return g


def rel_err(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("which", [0, 1, 2, 3])
def test_gradient_matches_central_differences(small_box, rng, which):
    nodes, tets, top, bottom = small_box
    term = make_terms(nodes, tets, top, bottom)[which]
    for _ in range(3):
        x = deformed(nodes, rng)
        assert term.admissible(x)
        g_fd = fd_gradient(term.value, x, h=1e-7)
        assert rel_err(term.gradient(x).ravel(), g_fd) <= 1e-6


@pytest.mark.parametrize("which", [0, 1, 3])
def test_hessian_matches_central_differences(small_box, rng, which):
    nodes, tets, top, bottom = small_box
    term = make_terms(nodes, tets, top, bottom)[which]
    free = np.ones(nodes.shape, bool)
    assembler = FreeDofAssembler([term.connectivity], free)
    for _ in range(3):
        x = deformed(nodes, rng)
        K = assembler.assemble_terms([term], x).toarray()          # the solver's (compiled) path
        K_fd = np.column_stack([fd_gradient(lambda y: term.gradient(y)[i // 3, i % 3], x, 1e-8)
                                for i in range(x.size)]).T
        assert np.allclose(K, K.T, rtol=0, atol=1e-10 * np.abs(K).max())
        assert rel_err(K, K_fd) <= 1e-6


def test_rest_state_has_zero_energy_and_gradient_without_gravity(small_box):
    nodes, tets, top, bottom = small_box
    terms = [t for t in make_terms(nodes, tets, top, bottom) if not isinstance(t, Gravity)]
    J = Composite(terms)
    assert abs(J.value(nodes)) < 1e-15
    assert np.abs(J.gradient(nodes)).max() < 1e-12


def test_homogeneous_stretch_matches_closed_form(small_box):
    nodes, tets, top, bottom = small_box
    lam, mu = 1000.0, 150.0
    F = np.array([[1.2, 0.1, 0.0], [0.0, 0.9, 0.05], [0.02, 0.0, 1.1]])
    x = nodes @ F.T
    bulk = BulkNeoHookean(nodes, tets, lam, mu)
    J = np.linalg.det(F)
    W = mu / 2 * (np.sum(F * F) - 3 - 2 * np.log(J)) + lam / 2 * (J - 1) ** 2
    volume = np.ptp(nodes[:, 0]) ** 3
    assert bulk.value(x) == pytest.approx(W * volume, rel=1e-12)
    # Skin on the plane z = const: the in-plane part of F acts on (x, y).
    lam_s, mu_s, t = 8000.0, 1600.0, 1e-3
    skin = SkinMembrane(nodes, top, lam_s, mu_s, t)
    Fp = F[:, :2]                                   # maps (dx, dy) to 3D
    C = Fp.T @ Fp
    j = np.sqrt(np.linalg.det(C))
    Ws = t * (mu_s / 2 * (np.trace(C) - 2 - 2 * np.log(j)) + lam_s / 2 * (j - 1) ** 2)
    assert skin.value(x) == pytest.approx(Ws * volume ** (2 / 3), rel=1e-12)


def test_skin_energy_invariant_under_rigid_rotation(small_box, rng):
    nodes, tets, top, bottom = small_box
    skin = SkinMembrane(nodes, top, 8000.0, 1600.0, 1e-3)
    x = deformed(nodes, rng)
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    Q *= np.sign(np.linalg.det(Q))
    y = x @ Q.T + rng.standard_normal(3)
    assert skin.value(y) == pytest.approx(skin.value(x), rel=1e-12)
    assert np.allclose(skin.gradient(y), skin.gradient(x) @ Q.T, atol=1e-12 * np.abs(skin.gradient(x)).max())


def test_inverted_tet_is_inadmissible(small_box):
    nodes, tets, top, bottom = small_box
    J = Composite(make_terms(nodes, tets, top, bottom))
    x = nodes.copy()
    x[:, 2] *= -1
    assert J.value(x) == np.inf


def test_psd_projection_clamps_only_negative_modes(rng):
    A = rng.standard_normal((5, 6, 6))
    A = A + np.swapaxes(A, 1, 2)
    P = project_psd(A)
    assert np.linalg.eigvalsh(P).min() > -1e-12
    B = np.einsum("nij,nkj->nik", A, A)   # already PSD: unchanged
    assert np.array_equal(project_psd(B), B)


@pytest.mark.parametrize("which, attribute", [(0, "lam"), (0, "mu"), (1, "lam"), (1, "mu")])
def test_modulus_gradient_is_the_derivative_of_the_gradient_in_that_modulus(small_box, rng, which, attribute):
    """The implicit Jacobian's ∂g/∂p for the moduli: exact, checked against a central difference."""
    import copy

    from breastcore.fem.terms import modulus_gradient

    nodes, tets, top, bottom = small_box
    term = make_terms(nodes, tets, top, bottom)[which]
    x = deformed(nodes, rng)
    h = 1e-3 * getattr(term, attribute)
    plus, minus = copy.copy(term), copy.copy(term)
    setattr(plus, attribute, getattr(term, attribute) + h)
    setattr(minus, attribute, getattr(term, attribute) - h)
    central = (plus.gradient(x) - minus.gradient(x)) / (2 * h)
    assert rel_err(modulus_gradient(term, attribute, x), central) <= 1e-9
    assert np.abs(central).max() > 0
