"""Sparse assembly of element Hessian blocks into the free-dof stiffness matrix.

The CSR pattern is computed once per mesh and boundary condition, with a table of
the CSR position of every element-block entry; each assembly is then one compiled
pass per term (:mod:`breastcore.fem.compiled`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from breastcore.fem.compiled import scatter_blocks


def element_dofs(connectivity):
    """Global dof numbers ``3 * node + xyz`` of each element, ``(n, 3k)``."""
    conn = np.asarray(connectivity)
    return (3 * conn[:, :, None] + np.arange(3)).reshape(len(conn), -1)


class FreeDofAssembler:
    """Assembles ``Σ_e Bᵀ H_e B`` restricted to the free dofs as a CSR matrix.

    Parameters
    ----------
    connectivities : sequence of (n_t, k_t) int arrays
        One connectivity per non-linear energy term, in the order of the blocks
        that :meth:`assemble` will receive.
    free : (N, 3) bool array
        True for each unknown dof.
    """

    def __init__(self, connectivities, free, mixed_min_dofs=None):
        free = np.asarray(free, dtype=bool).reshape(-1, 3)
        self.free = free.ravel()
        self.n_free = int(self.free.sum())
        number = np.full(self.free.size, -1, dtype=np.int64)
        number[self.free] = np.arange(self.n_free)
        self.free_index = number
        conns = [np.asarray(c, dtype=np.int64) for c in connectivities]
        # The pattern is built on the node graph and expanded to 3 × 3 dof blocks: an
        # element-entry key per dof pair (40 M on a 50k-node mesh) took 23 s to sort.
        n_nodes = len(free)
        pair_keys = [c[:, :, None] * n_nodes + c[:, None, :] for c in conns]
        pairs = np.unique(np.concatenate([k.ravel() for k in pair_keys]))      # sorted by (row node, column node)
        row_node, col_node = pairs // n_nodes, pairs % n_nodes
        free_count = free.sum(axis=1)
        width = free_count[col_node]                                          # free columns each node pair adds
        before = np.cumsum(width) - width                                     # exclusive, over all pairs
        first_pair = np.searchsorted(row_node, np.arange(n_nodes))
        row_length = np.bincount(row_node, weights=width, minlength=n_nodes).astype(np.int64)
        segment = before[np.minimum(first_pair, len(pairs) - 1)] if len(pairs) else np.zeros(n_nodes, np.int64)
        row_of_dof = np.flatnonzero(self.free) // 3                           # node of each free row
        indptr = np.concatenate([[0], np.cumsum(row_length[row_of_dof])])
        columns = number.reshape(-1, 3)[col_node]                             # (pairs, 3), −1 where fixed
        node_columns = columns[columns >= 0]                                  # each row node's columns, in order
        gather = np.repeat(segment[row_of_dof] - indptr[:-1], row_length[row_of_dof]) + np.arange(indptr[-1])
        self.indices = node_columns[gather].astype(np.int32)
        self.indptr = indptr.astype(np.int32)
        self.nnz = int(indptr[-1])
        row_start = np.where(free, indptr[np.maximum(number, 0)].reshape(-1, 3), -1)   # (N, 3)
        rank = np.cumsum(free, axis=1) - free                                 # rank of a free column in its node
        #: Per term, ``(n, 3k, 3k)`` int32: the index in the CSR data of each block entry, −1 if dropped.
        self.positions = []
        for conn, keys in zip(conns, pair_keys):
            n, k = conn.shape
            offset = before[np.searchsorted(pairs, keys)] - segment[conn][:, :, None]   # columns before node j
            offset = offset.astype(np.int32)[:, :, None, :, None]                         # (n, k, 1, k, 1)
            rows = row_start[conn].astype(np.int32)[:, :, :, None, None]                  # (n, k, 3, 1, 1)
            cols = np.where(free[conn], rank[conn], -1).astype(np.int32)[:, None, None]   # (n, 1, 1, k, 3)
            pos = np.where((rows >= 0) & (cols >= 0), rows + offset + cols, np.int32(-1))
            self.positions.append(pos.reshape(n, 3 * k, 3 * k))
        self._pattern = None
        self.mixed_min_dofs = mixed_min_dofs

    @property
    def pattern(self):
        """The :class:`~breastcore.linalg.pardiso.SymmetricPattern` of the assembled matrices (built once)."""
        if self._pattern is None:
            from breastcore.linalg.pardiso import SymmetricPattern
            self._pattern = SymmetricPattern(self.indptr, self.indices, self.n_free)
            self._pattern.mixed_min_dofs = self.mixed_min_dofs
        return self._pattern

    def assemble(self, blocks):
        """CSR matrix from ``[(connectivity, (n, 3k, 3k) blocks)]`` in constructor order."""
        data = np.zeros(self.nnz)
        for (_, H), positions in zip(blocks, self.positions):
            scatter_blocks(data, positions, np.ascontiguousarray(H, dtype=float))
        return self._matrix(data)

    def assemble_terms(self, terms, x, project=False):
        """CSR Hessian of ``terms`` (in constructor order) at node positions ``x``.

        A term with ``scatter_hessian(data, positions, x)`` adds its entries straight
        into the CSR data; the others give ``element_hessians(x)`` blocks. With
        ``project``, the PSD-projected Hessian: ``scatter_projected_hessian`` or
        ``projected_element_hessians``.
        """
        data = np.zeros(self.nnz)
        for term, positions in zip(terms, self.positions):
            if project and hasattr(term, "scatter_projected_hessian"):
                term.scatter_projected_hessian(data, positions, x)
            elif project:
                scatter_blocks(data, positions, np.ascontiguousarray(term.projected_element_hessians(x), dtype=float))
            elif hasattr(term, "scatter_hessian"):
                term.scatter_hessian(data, positions, x)
            else:
                scatter_blocks(data, positions, np.ascontiguousarray(term.element_hessians(x), dtype=float))
        return self._matrix(data)

    def _matrix(self, data):
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n_free, self.n_free))

    def restrict(self, vector):
        """Free-dof part of an ``(N, 3)`` array, as a flat vector."""
        return np.asarray(vector).ravel()[self.free]

    def expand(self, free_values, fixed):
        """``(N, 3)`` array with ``free_values`` in the free dofs and ``fixed`` elsewhere."""
        out = np.array(fixed, dtype=float, copy=True).ravel()
        out[self.free] = free_values
        return out.reshape(-1, 3)
