"""The free-dof CSR pattern of :class:`FreeDofAssembler` against a dof-level construction."""

import numpy as np
import scipy.sparse as sp

from breastcore.fem.assembly import FreeDofAssembler, element_dofs


def _reference_pattern(connectivities, free):
    """Canonical CSR pattern of all element dof pairs on the free dofs, built by scipy."""
    number = np.full(free.size, -1)
    number[free.ravel()] = np.arange(free.sum())
    rows, cols = [], []
    for conn in connectivities:
        dofs = number[element_dofs(conn)]
        r = np.broadcast_to(dofs[:, :, None], dofs.shape + dofs.shape[1:]).ravel()
        c = np.broadcast_to(dofs[:, None, :], dofs.shape + dofs.shape[1:]).ravel()
        keep = (r >= 0) & (c >= 0)
        rows.append(r[keep])
        cols.append(c[keep])
    n = int(free.sum())
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    K = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    K.sum_duplicates()
    K.sort_indices()
    return K, number


def test_pattern_is_canonical_and_every_block_entry_points_at_its_dof_pair(small_box, rng):
    nodes, tets, top, bottom = small_box
    free = rng.random(nodes.shape) > 0.3                     # nodes with 0, 1, 2 or 3 free dofs
    free[:, 1] |= ~np.isin(np.arange(len(nodes)), bottom)
    connectivities = [tets, top, np.unique(bottom)[:, None]]
    assembler = FreeDofAssembler(connectivities, free)
    reference, number = _reference_pattern(connectivities, free)
    np.testing.assert_array_equal(assembler.indptr, reference.indptr)
    np.testing.assert_array_equal(assembler.indices, reference.indices)
    assert assembler.nnz == reference.nnz
    row_of = np.repeat(np.arange(assembler.n_free), np.diff(assembler.indptr))
    for conn, positions in zip(connectivities, assembler.positions):
        dofs = number[element_dofs(conn)]
        r = np.broadcast_to(dofs[:, :, None], positions.shape)
        c = np.broadcast_to(dofs[:, None, :], positions.shape)
        dropped = (r < 0) | (c < 0)
        np.testing.assert_array_equal(positions < 0, dropped)
        kept = positions[~dropped]
        np.testing.assert_array_equal(row_of[kept], r[~dropped])
        np.testing.assert_array_equal(assembler.indices[kept], c[~dropped])
