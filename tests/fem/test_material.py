"""The bulk material law (fem/material.py), written once: its derivatives against finite
differences, and its two users (numpy kernel, compiled loops) against it."""

import numpy as np
import pytest

from breastcore.fem import material

LAM, MU = 1000.0, 150.0


def _energy(F):
    J = np.linalg.det(F)
    return material.energy_density(J, np.einsum("...ij,...ij->...", F, F), LAM, MU)


@pytest.fixture
def deformations():
    rng = np.random.default_rng(7)
    return np.eye(3) + 0.3 * rng.standard_normal((5, 3, 3)) * np.array([1, 1, 1])[None, :, None]


def test_the_first_piola_stress_is_the_derivative_of_the_energy(deformations):
    h = 1e-6
    for F in deformations:
        assert np.linalg.det(F) > 0
        P = material.first_piola(F, LAM, MU)
        fd = np.empty((3, 3))
        for k in range(3):
            for m in range(3):
                E = np.zeros((3, 3))
                E[k, m] = h
                fd[k, m] = (_energy(F + E) - _energy(F - E)) / (2 * h)
        np.testing.assert_allclose(P, fd, rtol=1e-7, atol=1e-7 * np.abs(P).max())


def test_the_tangent_modulus_is_the_derivative_of_the_stress(deformations):
    h = 1e-6
    for F in deformations:
        C = material.tangent_modulus(F, LAM, MU)
        for k in range(3):
            for m in range(3):
                E = np.zeros((3, 3))
                E[k, m] = h
                fd = (material.first_piola(F + E, LAM, MU) - material.first_piola(F - E, LAM, MU)) / (2 * h)
                np.testing.assert_allclose(C[:, :, k, m], fd, rtol=1e-6, atol=1e-6 * np.abs(C).max())


def test_the_principal_forms_are_the_derivatives_of_the_energy_in_the_stretches():
    s = np.array([1.2, 0.8, 1.05])
    J = s.prod()

    def psi(t):
        return material.energy_density(t.prod(), (t ** 2).sum(), LAM, MU)

    h = 1e-5
    for i in range(3):
        for j in range(3):
            ei, ej = np.eye(3)[i] * h, np.eye(3)[j] * h
            fd = (psi(s + ei + ej) - psi(s + ei - ej) - psi(s - ei + ej) + psi(s - ei - ej)) / (4 * h * h)
            k = 3 - i - j
            exact = material.stretch_hessian_diagonal(s[i], J, LAM, MU) if i == j else \
                material.stretch_hessian_off_diagonal(s[i], s[j], s[k], J, LAM)
            assert exact == pytest.approx(fd, rel=1e-5)
    # along a pure volume change σ(J') = s (J'/J)^(1/3): dW/dJ' = ψ_J + μ tr C / (3J)
    Jh = 1e-6
    scale = lambda J_: (J_ / J) ** (1 / 3)                          # noqa: E731
    fd = (psi(s * scale(J + Jh)) - psi(s * scale(J - Jh))) / (2 * Jh)
    assert material.pressure(J, LAM, MU) + MU * (s ** 2).sum() / (3 * J) == pytest.approx(fd, rel=1e-6)


def test_homogeneous_stretch_has_the_closed_form_energy_and_stress():
    a = 1.1
    F = np.diag([a, 1.0, 1.0])
    W = 0.5 * MU * (a * a - 1 - 2 * np.log(a)) + 0.5 * LAM * (a - 1) ** 2
    assert _energy(F) == pytest.approx(W, rel=1e-14)
    P11 = MU * a + (LAM * a * (a - 1) - MU) / a
    assert material.first_piola(F, LAM, MU)[0, 0] == pytest.approx(P11, rel=1e-14)


def test_the_numpy_kernel_and_the_compiled_loops_use_it():
    """Same numbers to the last bit: both evaluate fem/material.py's expressions."""
    from breastcore.fem import compiled, kernels
    J, trace_C = np.array([0.9, 1.0, 1.3]), np.array([2.9, 3.0, 3.5])
    W, c_inv, c_swap, c_vol = kernels.bulk_neo_hookean(J, trace_C, LAM, MU)
    np.testing.assert_array_equal(W, material.energy_density(J, trace_C, LAM, MU))
    np.testing.assert_array_equal(c_inv, material.stress_coefficient(J, LAM, MU))
    for j in range(3):
        swap, vol = compiled._tangent_coefficients(J[j], LAM, MU, 1.0)
        assert (swap, vol) == (c_swap[j], c_vol[j])
        assert compiled._stress_coefficient(J[j], LAM, MU) == c_inv[j]
