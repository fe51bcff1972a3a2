"""The compiled skin energy, gradient and Hessian scatter against their numpy references."""

import numpy as np
import pytest
from deformations import deformed

from breastcore.fem.assembly import element_dofs
from breastcore.fem.terms import SkinMembrane


@pytest.fixture
def skin(small_box):
    nodes, _, top, _ = small_box
    return SkinMembrane(nodes, top, lam=8000.0, mu=1600.0, thickness=1e-3)


def test_compiled_skin_energy_and_gradient_equal_the_numpy_sums(skin, small_box, rng):
    for amplitude in (0.15, 0.6):
        x = deformed(small_box[0], rng, amplitude)
        assert skin.value(x) == pytest.approx(skin.element_energies(x).sum(), rel=1e-13)
        forces = np.zeros(x.size)
        np.add.at(forces, element_dofs(skin.connectivity).ravel(), skin.element_gradients(x).ravel())
        np.testing.assert_allclose(skin.gradient(x).ravel(), forces, rtol=0, atol=1e-13 * np.abs(forces).max())


def test_compiled_skin_hessian_scatter_equals_the_numpy_blocks(skin, small_box, rng):
    """Identity positions: the scatter writes each triangle's 9 × 9 block, entry by entry."""
    x = deformed(small_box[0], rng, 0.6)
    n = len(skin.connectivity)
    positions = np.arange(n * 81, dtype=np.int32).reshape(n, 9, 9)
    data = np.zeros(n * 81)
    skin.scatter_hessian(data, positions, x)
    blocks = skin.element_hessians(x)
    np.testing.assert_allclose(data.reshape(n, 9, 9), blocks, rtol=0, atol=1e-13 * np.abs(blocks).max())


def test_compiled_skin_energy_is_infinite_for_a_degenerate_triangle(skin, small_box):
    x = small_box[0].copy()
    a, b, c = skin.connectivity[0]
    x[c] = 0.5 * (x[a] + x[b])                           # a collinear triangle: det g = 0
    assert skin.value(x) == np.inf and skin.checked_value(x) == np.inf


def test_compiled_skin_gradient_is_the_fd_derivative_of_the_compiled_energy(skin, small_box, rng):
    x = deformed(small_box[0], rng)
    g, h = skin.gradient(x), 1e-7
    for node, i in [(skin.connectivity[0, 0], 0), (skin.connectivity[1, 2], 2), (skin.connectivity[-1, 1], 1)]:
        xp, xm = x.copy(), x.copy()
        xp[node, i] += h
        xm[node, i] -= h
        assert g[node, i] == pytest.approx((skin.value(xp) - skin.value(xm)) / (2 * h), rel=1e-6,
                                           abs=1e-8 * np.abs(g).max())
