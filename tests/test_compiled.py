"""The compiled bulk energy, gradient and Hessian scatter against their numpy references."""

import numpy as np
import pytest

from breastcore.assembly import FreeDofAssembler, element_dofs
from breastcore.energy import BulkNeoHookean, Chassaignac, SkinMembrane

from test_energy import deformed


@pytest.fixture
def bulk(small_box):
    nodes, tets, top, bottom = small_box
    return BulkNeoHookean(nodes, tets, lam=1000.0, mu=150.0)


def test_compiled_bulk_energy_and_gradient_equal_the_numpy_sums(bulk, small_box, rng):
    nodes = small_box[0]
    for _ in range(3):
        x = deformed(nodes, rng)
        assert bulk.value(x) == pytest.approx(bulk.element_energies(x).sum(), rel=1e-13)
        forces = np.zeros(x.size)
        np.add.at(forces, element_dofs(bulk.connectivity).ravel(), bulk.element_gradients(x).ravel())
        np.testing.assert_allclose(bulk.gradient(x).ravel(), forces, rtol=0, atol=1e-13 * np.abs(forces).max())


def test_compiled_bulk_energy_is_infinite_for_an_inverted_tet(bulk, small_box):
    x = small_box[0].copy()
    x[bulk.connectivity[0, 0]] = x[bulk.connectivity[0, 1:]].mean(axis=0) * 2 - x[bulk.connectivity[0, 0]]
    assert bulk.value(x) == np.inf and not bulk.admissible(x)


def test_direct_scatter_equals_block_assembly_with_fixed_dofs(small_box, rng):
    """Entries on fixed dofs (position −1) are dropped, the others summed, for all three scatter paths."""
    nodes, tets, top, bottom = small_box
    terms = [BulkNeoHookean(nodes, tets, 1000.0, 150.0), SkinMembrane(nodes, top, 8000.0, 1600.0, 1e-3),
             Chassaignac(nodes, bottom, 100.0, 1e-3)]
    free = np.ones(nodes.shape, bool)
    free[bottom.ravel(), 1] = False
    free[bottom[0]] = False
    assembler = FreeDofAssembler([t.connectivity for t in terms], free)
    assert any((p < 0).any() for p in assembler.positions)
    x = deformed(nodes, rng)
    direct = assembler.assemble_terms(terms, x).toarray()
    blocks = assembler.assemble([(t.connectivity, t.element_hessians(x)) for t in terms]).toarray()
    np.testing.assert_allclose(direct, blocks, rtol=0, atol=1e-12 * np.abs(blocks).max())
    full = np.zeros((x.size, x.size))
    for t in terms:                                          # dense Σ_e Bᵀ H_e B, then restricted
        dofs = element_dofs(t.connectivity)
        for d, H in zip(dofs, t.element_hessians(x)):
            full[np.ix_(d, d)] += H
    keep = free.ravel()
    np.testing.assert_allclose(direct, full[np.ix_(keep, keep)], rtol=0, atol=1e-12 * np.abs(blocks).max())
