"""Sparse factorisation of a symmetric Hessian, reusable for many solves, and its inertia.

PARDISO (symmetric indefinite LDLᵀ, :mod:`breastcore.linalg.pardiso`) where installed, SuperLU
otherwise; single precision with iterative refinement on large matrices.
"""

from __future__ import annotations

import itertools
import logging
import warnings

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from breastcore.linalg import pardiso
from breastcore.linalg.pardiso import SymmetricPattern

log = logging.getLogger(__name__)


#: Matrices with at least this many rows are factorised in single precision and solved
#: by mixed-precision iterative refinement (see :class:`Factorization`), unless their
#: pattern sets its own threshold (a forward model's: ``SolverOptions.mixed_precision_min_dofs``,
#: default 0). On fine50k (145k dofs) factorisation and solve take 4.8 s against 10.6 s
#: (2 threads); the paper's levels gain 1.3-1.6× (``benchmarks/bench_factorization.py``).
MIXED_PRECISION_MIN_DOFS = 100_000
#: Refinement stops when ‖b − K x‖ ≤ this × ‖b‖. A double-precision factor reaches
#: ~1e-14; on the crushed standing states of fine50k refinement mostly levels off at 1.5-7e-12.
REFINEMENT_RTOL = 1e-10
#: Refinement steps of one solve before the matrix is factorised in double instead.
REFINEMENT_MAX_STEPS = 10


class Factorization:
    r"""Sparse factorisation of a symmetric free-dof Hessian, reusable for many solves.

    Uses MKL PARDISO (symmetric indefinite LDLᵀ) where ``pypardiso`` is installed,
    about 5× faster than SuperLU on these meshes; SuperLU in symmetric mode
    otherwise. ``negative_pivots`` is the number of negative eigenvalues (the
    inertia) when PARDISO reports it, else ``None``.

    Parameters
    ----------
    K : (n, n) sparse matrix
        Symmetric; only its upper triangle is read by PARDISO.
    pattern : SymmetricPattern, optional
        The pattern ``K`` is known to have (e.g. a Newton solve's Hessians): its
        symbolic analysis is reused and only the numeric factorisation is done.
        Without it, or if ``K`` does not match it, the factorisation has a
        private PARDISO handle.
    mixed : bool, optional
        Factorise in single precision and refine in double (default: when PARDISO is
        available and ``n ≥`` the pattern's ``mixed_min_dofs``, or
        :data:`MIXED_PRECISION_MIN_DOFS` if that is None or ``K`` has no matching pattern).

    Notes
    -----
    Mixed precision (Langou et al. 2006): with the single-precision factor
    :math:`M \approx K`, :meth:`solve` iterates
    :math:`x_{k+1} = x_k + M^{-1}(b - K x_k)`, the residual in double, until
    :math:`\|b - K x\| \le` :data:`REFINEMENT_RTOL` :math:`\|b\|`. This
    converges when :math:`\kappa(K)\,\varepsilon_{single} < 1`; if the residual
    stops falling first (a crushed tet makes :math:`K` too ill-conditioned), the
    matrix is factorised again in double precision, once, and that factor is used
    from then on (``mixed`` becomes False). The inertia of a single-precision
    factor is that of :math:`M`.
    """

    _tokens = itertools.count()

    def __init__(self, K: sp.csr_matrix, pattern: SymmetricPattern | None = None, mixed: bool | None = None):
        self.shape = K.shape
        self.negative_pivots = None
        self.mixed = False
        self.refinement_steps = 0
        self._token = next(Factorization._tokens)
        if pardiso.available():
            K = K.tocsr()
            if pattern is None or not pattern.matches(K):
                if not K.has_canonical_format:
                    K = K.copy()
                    K.sum_duplicates()
                pattern = SymmetricPattern(K.indptr, K.indices, K.shape[0])
            self._pattern = pattern
            self.mixed = single_precision(pattern) if mixed is None else bool(mixed)
            self._K = K if self.mixed else None
            self._factorize(K.data[pattern.upper])
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("error", spla.MatrixRankWarning)
                self._lu = spla.splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True})

    def _factorize(self, upper):
        handle = self._pattern.handle_to_factorize(single=self.mixed)
        self._data = np.ascontiguousarray(upper, dtype=handle.dtype)
        self.negative_pivots = handle.factorize(self._data, self._token)

    def _solve_factor(self, b):
        handle = self._pattern.handle(single=self.mixed)
        if not handle.holds(self._token):                            # another factor took the handle, or freed it
            handle = self._pattern.handle_to_factorize(single=self.mixed)
            handle.factorize(self._data, self._token)
        return handle.solve(self._data, b).astype(float, copy=False)

    def solve(self, b, rtol=REFINEMENT_RTOL):
        """``K⁻¹ b``; a mixed-precision factor refines until ``‖b − K x‖ ≤ rtol ‖b‖`` (per column).

        A looser ``rtol`` than the default suits an inexact Newton direction: a single-precision
        solve usually meets 1e-3 with no refinement step (``SolverOptions.step_rtol``).
        """
        b = np.asarray(b, dtype=float)
        if not pardiso.available():
            return self._lu.solve(b)
        if not self.mixed:
            return self._solve_factor(b)
        x = self._refine(b, rtol)
        if x is not None:
            return x
        log.debug("mixed-precision refinement stalled after %d steps: double precision", self.refinement_steps)
        upper = self._K.data[self._pattern.upper]
        self.mixed, self._K = False, None
        self._factorize(upper)
        return self._solve_factor(b)

    def _refine(self, b, rtol=REFINEMENT_RTOL):
        """Mixed-precision iterative refinement of ``K x = b`` to ``rtol``; ``None`` if it stalls."""
        scale = np.linalg.norm(b, axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        x = self._solve_factor(b)
        best = np.inf
        for _ in range(REFINEMENT_MAX_STEPS + 1):
            r = b - self._K @ x
            ratio = float(np.max(np.linalg.norm(r, axis=0) / scale))
            if ratio <= rtol:
                return x
            if not ratio < 0.5 * best:                              # not converging: κ ε_single ≳ 1
                return None
            best = ratio
            x = x + self._solve_factor(r)
            self.refinement_steps += 1
        return None


def single_precision(pattern: SymmetricPattern) -> bool:
    """Whether matrices of ``pattern`` are factorised in single precision by default: at least its
    ``mixed_min_dofs`` rows (:data:`MIXED_PRECISION_MIN_DOFS` if that is None)."""
    threshold = MIXED_PRECISION_MIN_DOFS if pattern.mixed_min_dofs is None else pattern.mixed_min_dofs
    return pattern.n >= threshold


def analyse(pattern: SymmetricPattern):
    """PARDISO's symbolic analysis of ``pattern`` now, in the precision its factorisations use by
    default (:func:`single_precision`); a no-op without PARDISO or where it is done already."""
    if pardiso.available():
        pattern.analyse(single_precision(pattern))


def shift_diagonal(K, sigma):
    """``K + σI`` (σ a float, or an ``(n,)`` array for ``K + diag(σ)``) with the sparsity structure
    of ``K`` (CSR, every diagonal entry stored).

    ``K + σ * identity`` would drop ``K``'s explicit zeros, and the result would
    no longer match ``K``'s :class:`SymmetricPattern` (a new symbolic analysis,
    twice the cost of the numeric factorisation). Falls back to the sparse sum
    when a diagonal entry is not stored.
    """
    K = K.tocsr()
    rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    diagonal = np.flatnonzero(K.indices == rows)
    if diagonal.size != K.shape[0]:
        return (K + sp.diags(np.broadcast_to(sigma, K.shape[0]), format="csr")).tocsr()
    shifted = K.copy()
    shifted.data[diagonal] += sigma
    return shifted


def factor_solve(K, g, pattern=None, rtol=REFINEMENT_RTOL):
    """``(factor, −K⁻¹ g)`` solved to ``rtol`` (:meth:`Factorization.solve`); ``(None, None)`` if it fails."""
    try:
        factor = Factorization(K, pattern)
        d = -factor.solve(g, rtol)
    except (RuntimeError, spla.MatrixRankWarning, ValueError):
        return None, None
    if not np.all(np.isfinite(d)):
        return None, None
    return factor, d


def hessian_factor(problem, z, K=None):
    """The factorised exact free-dof Hessian at ``z`` (None if it is singular).

    One numeric factorisation (the pattern's symbolic analysis is reused). ``K``: that
    Hessian, if the caller has already assembled it (``problem.hessian(z)`` otherwise).
    """
    try:
        return Factorization(problem.hessian(z) if K is None else K, getattr(problem, "pattern", None))
    except (RuntimeError, ValueError, spla.MatrixRankWarning):
        return None


def hessian_inertia(problem, z, K=None):
    """Negative eigenvalues of the exact free-dof Hessian at ``z`` (None without PARDISO's inertia,
    or where it is singular); see :func:`hessian_factor`."""
    factor = hessian_factor(problem, z, K)
    return None if factor is None else factor.negative_pivots
