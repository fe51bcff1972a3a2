"""Sparse assembly of element Hessian blocks into the free-dof stiffness matrix.

The CSR pattern is computed once per mesh and boundary condition, with a table of
the CSR position of every element-block entry; each assembly is then one compiled
pass per term (:mod:`breastcore.compiled`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .compiled import scatter_blocks


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

    def __init__(self, connectivities, free):
        free = np.asarray(free, dtype=bool).ravel()
        self.free = free
        self.n_free = int(free.sum())
        number = np.full(free.size, -1, dtype=np.int64)
        number[free] = np.arange(self.n_free)
        self.free_index = number
        keys = []
        for conn in connectivities:
            dofs = number[element_dofs(conn)]
            m = dofs.shape[1]
            rows = np.broadcast_to(dofs[:, :, None], (len(dofs), m, m))
            cols = np.broadcast_to(dofs[:, None, :], (len(dofs), m, m))
            keys.append(np.where((rows >= 0) & (cols >= 0), rows * self.n_free + cols, -1))
        kept = np.concatenate([k[k >= 0] for k in keys]) if keys else np.zeros(0, np.int64)
        unique = np.unique(kept)
        #: Per term, ``(n, 3k, 3k)`` int32: the index in the CSR data of each block entry, −1 if dropped.
        self.positions = [np.where(k >= 0, np.searchsorted(unique, k), -1).astype(np.int32) for k in keys]
        self.indices = (unique % self.n_free).astype(np.int32)
        row_of = unique // self.n_free
        self.indptr = np.searchsorted(row_of, np.arange(self.n_free + 1)).astype(np.int32)
        self.nnz = unique.size
        self._pattern = None

    @property
    def pattern(self):
        """The :class:`~breastcore.solver.SymmetricPattern` of the assembled matrices (built once)."""
        if self._pattern is None:
            from .solver import SymmetricPattern
            self._pattern = SymmetricPattern(self.indptr, self.indices, self.n_free)
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
