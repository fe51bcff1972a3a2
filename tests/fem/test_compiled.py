"""The compiled bulk energy, gradient and Hessian scatter against their numpy references."""

import numpy as np
import pytest
from deformations import deformed

from breastcore.fem.assembly import FreeDofAssembler, element_dofs
from breastcore.fem.terms import BulkNeoHookean, Chassaignac, SkinMembrane


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


def _scatter_projected(bulk, x, clamp=True):
    """Dense ``(T·12, 12)`` blocks from the compiled projected scatter (identity positions)."""
    from breastcore.fem import compiled
    n = len(bulk.connectivity)
    positions = np.arange(n * 144, dtype=np.int32).reshape(n, 12, 12)
    data = np.zeros(n * 144)
    compiled.scatter_bulk_hessian_projected(data, positions, np.ascontiguousarray(x), bulk.connectivity,
                                            bulk.shape_gradients, bulk.volume, bulk.lam, bulk.mu, clamp)
    return data.reshape(n, 12, 12)


def _deformed_states(small_box, rng, lam):
    """A bulk term with ``λ = lam`` and two random states, mildly and strongly deformed."""
    bulk = BulkNeoHookean(small_box[0], small_box[1], lam, 150.0)
    return [(bulk, deformed(small_box[0], rng, amplitude)) for amplitude in (0.15, 0.6)]


@pytest.mark.parametrize("lam", [1000.0, 20.0, 2e5])
def test_analytic_eigensystem_rebuilds_the_exact_bulk_hessian(small_box, rng, lam):
    """Unclamped, the twist, flip and scaling modes with their eigenvalues sum to ``|τ| Bᵀ C B`` exactly."""
    for bulk, x in _deformed_states(small_box, rng, lam):
        exact = bulk.element_hessians(x)
        np.testing.assert_allclose(_scatter_projected(bulk, x, clamp=False), exact, rtol=0,
                                   atol=1e-10 * np.abs(exact).max())


@pytest.mark.parametrize("lam", [1000.0, 20.0, 2e5])
def test_analytic_projection_equals_the_numerical_eigh_projection_of_c(small_box, rng, lam):
    """Clamped: the analytic modes equal ``eigh`` of the 9×9 tangent modulus, clamped, and are PSD."""
    for bulk, x in _deformed_states(small_box, rng, lam):
        reference = bulk.projected_element_hessians(x)
        compiled_blocks = _scatter_projected(bulk, x)
        scale = np.abs(bulk.element_hessians(x)).max()
        np.testing.assert_allclose(compiled_blocks, reference, rtol=0, atol=1e-10 * scale)
        assert np.linalg.eigvalsh(compiled_blocks).min() >= -1e-10 * scale
        # the test must be able to fail: some blocks were indefinite and changed
        assert np.linalg.eigvalsh(bulk.element_hessians(x)).min() < -1e-6 * scale
        assert np.abs(compiled_blocks - bulk.element_hessians(x)).max() > 1e-6 * scale


def test_projection_keeps_the_exact_blocks_of_psd_tangent_moduli(small_box):
    """At a pure uniform stretch with μ > |Ψ_J| σ the tangent modulus is PSD: the block is the exact one."""
    bulk = BulkNeoHookean(small_box[0], small_box[1], 1000.0, 150.0)
    x = small_box[0] * 1.01
    assert np.linalg.eigvalsh(bulk.tangent_moduli(x)).min() > 0
    exact = bulk.element_hessians(x)
    np.testing.assert_allclose(_scatter_projected(bulk, x), exact, rtol=0, atol=1e-11 * np.abs(exact).max())


def test_tangent_moduli_are_the_fd_derivative_of_the_stress(small_box, rng):
    """``C = ∂P/∂F`` against central differences of ``P = μF + c_inv F⁻ᵀ`` (the stress in the kernel)."""
    from breastcore.fem import kernels
    bulk = BulkNeoHookean(small_box[0], small_box[1], 1000.0, 150.0)
    x = deformed(small_box[0], rng)
    F = bulk.deformation_gradient(x)[:3]

    def stress(F):
        J = np.linalg.det(F)
        _, c_inv, _, _ = kernels.bulk_neo_hookean(J, np.einsum("nij,nij->n", F, F), bulk.lam, bulk.mu)
        return bulk.mu * F + c_inv[:, None, None] * np.linalg.inv(F).transpose(0, 2, 1)

    h = 1e-6
    fd = np.zeros((3, 9, 9))
    for kl in range(9):
        dF = np.zeros((3, 3))
        dF.flat[kl] = h
        fd[:, :, kl] = ((stress(F + dF) - stress(F - dF)) / (2 * h)).reshape(3, 9)
    np.testing.assert_allclose(bulk.tangent_moduli(x)[:3], fd, rtol=0, atol=1e-6 * np.abs(fd).max())


def test_compiled_reference_geometry_reproduces_linear_fields(small_box):
    """``Σ_a X_a ⊗ ∇N_a = I`` and ``Σ_a ∇N_a = 0`` per tet; the volumes sum to the box's and equal
    numpy's ``det``."""
    nodes, tets = small_box[0], small_box[1]
    bulk = BulkNeoHookean(nodes, tets, 1000.0, 150.0)
    G = bulk.shape_gradients
    identity = np.broadcast_to(np.eye(3), (len(tets), 3, 3))
    np.testing.assert_allclose(np.einsum("nai,naj->nij", nodes[tets], G), identity, rtol=0, atol=1e-12)
    np.testing.assert_allclose(G.sum(axis=1), 0.0, atol=1e-12 * np.abs(G).max())
    assert bulk.volume.sum() == pytest.approx(np.prod(np.ptp(nodes, axis=0)), rel=1e-12)
    edges = np.swapaxes(nodes[tets[:, 1:]] - nodes[tets[:, :1]], 1, 2)
    np.testing.assert_allclose(bulk.volume, np.linalg.det(edges) / 6, rtol=1e-13)


def test_reference_mesh_with_an_inverted_tet_is_rejected(small_box):
    nodes, tets = small_box[0], small_box[1].copy()
    tets[0, [0, 1]] = tets[0, [1, 0]]
    with pytest.raises(ValueError, match="non-positive"):
        BulkNeoHookean(nodes, tets, 1000.0, 150.0)


def test_deformation_extremes_of_a_homogeneous_stretch_and_of_a_random_state(small_box, rng):
    """At ``x = diag(a, b, c) X`` every tet has ``det F = abc`` and largest stretch ``max(a, b, c)``;
    at a random state, numpy's ``det`` and ``eigvalsh`` of ``FᵀF`` give the same extremes."""
    bulk = BulkNeoHookean(small_box[0], small_box[1], 1000.0, 150.0)
    stretch = np.array([1.3, 0.6, 0.9])
    min_det, largest = bulk.deformation_extremes(small_box[0] * stretch)
    assert min_det == pytest.approx(np.prod(stretch), rel=1e-12)
    assert largest == pytest.approx(stretch.max(), rel=1e-12)
    x = deformed(small_box[0], rng, 0.6)
    F = bulk.deformation_gradient(x)
    min_det, largest = bulk.deformation_extremes(x)
    assert min_det == pytest.approx(np.linalg.det(F).min(), rel=1e-12)
    assert largest == pytest.approx(np.sqrt(np.linalg.eigvalsh(np.einsum("nki,nkj->nij", F, F)).max()), rel=1e-12)
