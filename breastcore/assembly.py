"""Sparse assembly of element Hessian blocks into the free-dof stiffness matrix.

The CSR pattern is computed once per mesh and boundary condition; each assembly is
then one ``np.bincount`` per term, with no Python loop over elements.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


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
        self._keep = []
        for conn in connectivities:
            dofs = number[element_dofs(conn)]
            rows = np.repeat(dofs[:, :, None], dofs.shape[1], axis=2).ravel()
            cols = np.repeat(dofs[:, None, :], dofs.shape[1], axis=1).ravel()
            keep = (rows >= 0) & (cols >= 0)
            self._keep.append(keep)
            keys.append(rows[keep] * self.n_free + cols[keep])
        unique = np.unique(np.concatenate(keys)) if keys else np.zeros(0, np.int64)
        self._positions = [np.searchsorted(unique, k) for k in keys]
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
        for (_, H), keep, pos in zip(blocks, self._keep, self._positions):
            data += np.bincount(pos, weights=H.ravel()[keep], minlength=self.nnz)
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n_free, self.n_free))

    def restrict(self, vector):
        """Free-dof part of an ``(N, 3)`` array, as a flat vector."""
        return np.asarray(vector).ravel()[self.free]

    def expand(self, free_values, fixed):
        """``(N, 3)`` array with ``free_values`` in the free dofs and ``fixed`` elsewhere."""
        out = np.array(fixed, dtype=float, copy=True).ravel()
        out[self.free] = free_values
        return out.reshape(-1, 3)
