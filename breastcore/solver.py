"""Newton's method for the discrete energy, with the exact sparse Hessian.

Robustness measures (issue #2, section 4):

- a descent check on the Newton direction; when it fails, or the line search does,
  the step is recomputed with a positive semi-definite Hessian (only when needed:
  the bulk's tangent modulus ∂²W/∂F² and each skin block with their negative
  eigenvalues set to zero), then with a diagonal shift;
- a backtracking line search in which an inverted tet or a degenerate skin triangle
  counts as infinite energy;
- an Armijo test on the energy that falls back to a decrease of the gradient norm
  once energy differences are below round-off (the last digits of a converged solve).
"""

from __future__ import annotations

import ctypes
import itertools
import logging
import os
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

try:
    import pypardiso as _pardiso
    # Each new PARDISO handle otherwise searches site-packages for libmkl_rt (0.15 s).
    os.environ.setdefault("PYPARDISO_MKL_RT", _pardiso.ps.libmkl._name)
except (ImportError, AttributeError):  # MKL is x86-64 only: SuperLU instead
    _pardiso = None

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class NewtonResult:
    """Outcome of one Newton solve (frozen: it is a record, not a state).

    Attributes
    ----------
    x : (n,) array
        Free dofs at the last iterate, m.
    success : bool
        Whether ``gradient_norm <= tolerance``.
    iterations : int
        Newton iterations taken.
    gradient_norm : float
        Euclidean norm of the free-dof gradient at ``x``, N.
    tolerance : float
        The stopping tolerance on ``gradient_norm``, N.
    energy : float
        Energy at ``x``, J.
    projected_steps : int
        Iterations that needed the PSD projection or a shift.
    history : tuple of float
        Gradient norm before each iteration, N.
    message : str
        Why it stopped.
    negative_pivots : int or None
        Negative eigenvalues of the exact Hessian (PARDISO's inertia; ``None`` if
        unknown) where it was last factorised: at ``x`` if ``inertia_at_x``, else at
        the iterate before the last step (a Newton solve factorises before it steps).
    inertia_at_x : bool
        Whether ``negative_pivots`` is the inertia at ``x`` itself. Non-zero
        inertia at ``x`` means the equilibrium is a saddle, not a minimum.
    """

    x: np.ndarray
    success: bool
    iterations: int
    gradient_norm: float
    tolerance: float
    energy: float
    projected_steps: int
    history: tuple
    message: str
    negative_pivots: int | None = None
    inertia_at_x: bool = False


def hessian_inertia(problem, z, K=None):
    """Negative eigenvalues of the exact free-dof Hessian at ``z`` (None without PARDISO's inertia).

    One numeric factorisation (the pattern's symbolic analysis is reused). ``K``: that
    Hessian, if the caller has already assembled it (``problem.hessian(z)`` otherwise).
    """
    try:
        return Factorization(problem.hessian(z) if K is None else K, getattr(problem, "pattern", None)).negative_pivots
    except (RuntimeError, ValueError, spla.MatrixRankWarning):     # singular: no inertia to report
        return None


#: Threads PARDISO may use (environment variable ``BREASTCORE_PARDISO_THREADS``, default 1).
#: On this project's 2-core machines two solves (or a solve and another job) often run at
#: once; a 2-thread PARDISO then waits for a busy core and a 25 ms factorisation takes
#: 60-200 ms, a solve 40-160 ms instead of 2 ms (measured, see docs/benchmarks.md).
PARDISO_THREADS_ENV = "BREASTCORE_PARDISO_THREADS"


def _set_pardiso_threads(lib):
    try:
        threads = int(os.environ.get(PARDISO_THREADS_ENV, "1"))
    except ValueError:
        threads = 1
    if threads > 0:
        try:                                                         # MKL serves only PARDISO here (numpy
            lib.MKL_Set_Num_Threads.argtypes = [ctypes.c_int]        # has its own BLAS)
            lib.MKL_Set_Num_Threads(threads)
        except AttributeError:                                       # not an MKL runtime: keep its default
            pass


class _Pardiso:
    """One MKL PARDISO instance for a real symmetric indefinite matrix (``mtype = -2``).

    Called through ``ctypes`` on the MKL that ``pypardiso`` ships, with PARDISO's
    default ``iparm`` (as ``pypardiso`` uses it). The phases are split so that the
    symbolic analysis (phase 11: fill-reducing ordering) is done once per sparsity
    pattern and each new matrix only needs the numeric factorisation (phase 22).
    """

    _function = None

    def __init__(self, n, ia, ja, single=False):
        if _Pardiso._function is None:
            lib = ctypes.CDLL(os.environ.get("PYPARDISO_MKL_RT") or _pardiso.ps.libmkl._name)
            _set_pardiso_threads(lib)
            fn = lib.pardiso
            p_int = ctypes.POINTER(ctypes.c_int32)
            fn.argtypes = [ctypes.POINTER(ctypes.c_int64), p_int, p_int, p_int, p_int, p_int, ctypes.c_void_p,
                           p_int, p_int, p_int, p_int, p_int, p_int, ctypes.c_void_p, ctypes.c_void_p, p_int]
            fn.restype = None
            _Pardiso._function = fn
        self.n = int(n)
        self.ia = np.ascontiguousarray(ia, dtype=np.int32)          # 1-based CSR of the upper triangle
        self.ja = np.ascontiguousarray(ja, dtype=np.int32)
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = np.zeros(64, dtype=np.int32)
        self.dtype = np.float32 if single else np.float64
        if single:                                                   # PARDISO's defaults for mtype −2, set
            self.iparm[[0, 1, 9, 17, 18, 20, 27]] = [1, 2, 8, -1, -1, 1, 1]   # explicitly, plus single precision
        self.perm = np.zeros(self.n, dtype=np.int32)
        self.analysed = False
        self.owner = None                                            # token of the factor held now

    def _call(self, phase, data, b=None, nrhs=1):
        c_int = ctypes.c_int32
        p_int = ctypes.POINTER(c_int)
        error = c_int(0)
        x = np.zeros_like(b) if b is not None else None
        self._function(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(c_int(1)),
                       ctypes.byref(c_int(1)), ctypes.byref(c_int(-2)), ctypes.byref(c_int(phase)),
                       ctypes.byref(c_int(self.n)), data.ctypes.data if data is not None else None,
                       self.ia.ctypes.data_as(p_int), self.ja.ctypes.data_as(p_int),
                       self.perm.ctypes.data_as(p_int), ctypes.byref(c_int(nrhs)),
                       self.iparm.ctypes.data_as(p_int), ctypes.byref(c_int(0)),
                       b.ctypes.data if b is not None else None, x.ctypes.data if x is not None else None,
                       ctypes.byref(error))
        if error.value != 0:
            raise RuntimeError(f"PARDISO phase {phase} failed with error {error.value}")
        return x

    def factorize(self, data, owner):
        """Numeric factorisation of the matrix with upper-triangle values ``data``."""
        self.owner = None
        if not self.analysed:
            self._call(11, data)
            self.analysed = True
        self._call(22, data)
        self.owner = owner
        return int(self.iparm[22])                                   # number of negative pivots

    def solve(self, data, b):
        b = np.asfortranarray(b, dtype=self.dtype)
        nrhs = 1 if b.ndim == 1 else b.shape[1]
        return np.ascontiguousarray(self._call(33, data, b, nrhs))

    def free(self):
        if self.analysed and self._function is not None:
            try:
                self._call(-1, None)
            except Exception:                                        # noqa: BLE001 - interpreter shutdown
                pass
            self.analysed = False

    def __del__(self):
        self.free()


class SymmetricPattern:
    """The fixed sparsity pattern of a symmetric CSR matrix, with one reusable PARDISO handle.

    A Newton solve factorises a matrix of the same pattern at every iteration; this
    object keeps the PARDISO symbolic analysis (ordering) of that pattern, so that
    :class:`Factorization` only does the numeric phase. The handle holds one numeric
    factor at a time: a :class:`Factorization` whose factor was replaced by a later
    one refactorises itself on its next ``solve`` (results never mix).

    Parameters
    ----------
    indptr, indices : int arrays
        CSR structure (sorted column indices) of the full symmetric matrix.
    n : int
        Matrix size.
    """

    def __init__(self, indptr, indices, n):
        self.n = int(n)
        self.indptr = np.asarray(indptr)
        self.indices = np.asarray(indices)
        rows = np.repeat(np.arange(self.n), np.diff(self.indptr))
        upper = self.indices >= rows
        self.upper = np.flatnonzero(upper)                           # positions of the upper triangle in data
        counts = np.bincount(rows[upper], minlength=self.n)
        self.ia = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32) + 1
        self.ja = self.indices[upper].astype(np.int32) + 1
        self._handles = {}

    def matches(self, K):
        return (K.shape == (self.n, self.n) and K.format == "csr" and K.has_sorted_indices
                and (K.indptr is self.indptr or np.array_equal(K.indptr, self.indptr))
                and (K.indices is self.indices or np.array_equal(K.indices, self.indices)))

    def handle(self, single=False):
        """The PARDISO handle of this pattern (a separate one for single precision)."""
        if single not in self._handles:
            self._handles[single] = _Pardiso(self.n, self.ia, self.ja, single)
        return self._handles[single]

    def release(self):
        """Free PARDISO's memory for this pattern (it is re-analysed on next use)."""
        for handle in self._handles.values():
            handle.free()
        self._handles = {}


#: Matrices with at least this many rows are factorised in single precision and solved
#: by mixed-precision iterative refinement (see :class:`Factorization`). On fine50k
#: (145k dofs) factorisation and solve take 4.8 s against 10.6 s (2 threads). Smaller
#: meshes gain 1.2-2.2× too (``benchmarks/bench_factorization.py``), but stay in double
#: precision: their solves, and the paper scene's results, stay as they were.
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
        Factorise in single precision and refine in double (default: when
        ``n ≥`` :data:`MIXED_PRECISION_MIN_DOFS` and PARDISO is available).

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
        if _pardiso is not None:
            K = K.tocsr()
            if pattern is None or not pattern.matches(K):
                if not K.has_canonical_format:
                    K = K.copy()
                    K.sum_duplicates()
                pattern = SymmetricPattern(K.indptr, K.indices, K.shape[0])
            self._pattern = pattern
            self.mixed = K.shape[0] >= MIXED_PRECISION_MIN_DOFS if mixed is None else bool(mixed)
            self._K = K if self.mixed else None
            self._factorize(K.data[pattern.upper])
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("error", spla.MatrixRankWarning)
                self._lu = spla.splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True})

    def _factorize(self, upper):
        handle = self._pattern.handle(single=self.mixed)
        self._data = np.ascontiguousarray(upper, dtype=handle.dtype)
        self.negative_pivots = handle.factorize(self._data, self._token)

    def _solve_factor(self, b):
        handle = self._pattern.handle(single=self.mixed)
        if handle.owner != self._token:                              # another factor took the handle
            handle.factorize(self._data, self._token)
        return handle.solve(self._data, b).astype(float, copy=False)

    def solve(self, b):
        b = np.asarray(b, dtype=float)
        if _pardiso is None:
            return self._lu.solve(b)
        if not self.mixed:
            return self._solve_factor(b)
        x = self._refine(b)
        if x is not None:
            return x
        log.debug("mixed-precision refinement stalled after %d steps: double precision", self.refinement_steps)
        upper = self._K.data[self._pattern.upper]
        self.mixed, self._K = False, None
        self._factorize(upper)
        return self._solve_factor(b)

    def _refine(self, b):
        """Mixed-precision iterative refinement of ``K x = b``; ``None`` if it stalls."""
        scale = np.linalg.norm(b, axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        x = self._solve_factor(b)
        best = np.inf
        for _ in range(REFINEMENT_MAX_STEPS + 1):
            r = b - self._K @ x
            ratio = float(np.max(np.linalg.norm(r, axis=0) / scale))
            if ratio <= REFINEMENT_RTOL:
                return x
            if not ratio < 0.5 * best:                              # not converging: κ ε_single ≳ 1
                return None
            best = ratio
            x = x + self._solve_factor(r)
            self.refinement_steps += 1
        return None


def shift_diagonal(K, sigma):
    """``K + σI`` with the sparsity structure of ``K`` (CSR, every diagonal entry stored).

    ``K + σ * identity`` would drop ``K``'s explicit zeros, and the result would
    no longer match ``K``'s :class:`SymmetricPattern` (a new symbolic analysis,
    twice the cost of the numeric factorisation). Falls back to the sparse sum
    when a diagonal entry is not stored.
    """
    K = K.tocsr()
    rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    diagonal = np.flatnonzero(K.indices == rows)
    if diagonal.size != K.shape[0]:
        return (K + sigma * sp.identity(K.shape[0], format="csr")).tocsr()
    shifted = K.copy()
    shifted.data[diagonal] += sigma
    return shifted


def _dot(a, b):
    """``a · b`` without BLAS (a threaded BLAS dot stalls when the other core is busy)."""
    return float(np.einsum("i,i->", a, b))


def _norm(a):
    """Euclidean norm of a vector, without BLAS (see :func:`_dot`)."""
    return float(np.sqrt(np.einsum("i,i->", a, a)))


def _factor_solve(K, g, pattern=None):
    try:
        factor = Factorization(K, pattern)
        d = -factor.solve(g)
    except (RuntimeError, spla.MatrixRankWarning, ValueError):
        return None, None
    if not np.all(np.isfinite(d)):
        return None, None
    return factor, d


def _line_search(problem, z, d, energy, g, g_norm, min_step=2.0**-30, expand=False):
    """Backtracking search on ``problem.value``; returns (step, z_new, energy_new) or None.

    With ``expand``, an accepted full step is doubled (up to 2¹⁰) while the energy keeps
    decreasing. Used for the modified (projected or shifted) Hessians only: near a
    saddle their step along the escape direction is far too short, and without
    expansion leaving the saddle took up to 100 iterations of growing gradient.
    """
    slope = _dot(g, d)
    scale = abs(energy) + problem.energy_scale
    step = 1.0
    while step >= min_step:
        z_new = z + step * d
        e_new = problem.value(z_new)
        if np.isfinite(e_new):
            if e_new <= energy + 1e-4 * step * slope:
                if expand and step == 1.0:
                    while step < 2.0**10:
                        z_try = z + 2.0 * step * d
                        e_try = problem.value(z_try)
                        if not (np.isfinite(e_try) and e_try < e_new):
                            break
                        step, z_new, e_new = 2.0 * step, z_try, e_try
                return step, z_new, e_new
            # Below round-off the energy cannot rank the two points: use the gradient.
            if abs(e_new - energy) <= 1e-12 * scale and abs(step * slope) <= 1e-11 * scale:
                if _norm(problem.gradient(z_new)) < g_norm:
                    return step, z_new, e_new
        step *= 0.5
    return None


#: Iterations without progress after which :func:`newton` stops (see :func:`_stagnated`).
STAGNATION_WINDOW = 10


def _stagnated(history, energies, scale):
    """Whether the last :data:`STAGNATION_WINDOW` iterations made no progress at all.

    No progress: the gradient norm never fell below 0.9 × its best before the
    window, and the energy changed by at most 1e-12 × ``scale`` (round-off).
    This happens when the tolerance lies below the gradient's round-off floor
    (e.g. λ/μ = 1e4 with a large load, where the forces cancel to ~1e-9 N):
    without the test such a solve spends every iteration of every continuation
    halving there (1,600 iterations in one no-inverse-crime identification step).
    """
    w = STAGNATION_WINDOW
    if len(history) <= 2 * w:
        return False
    best_before = min(history[:-w])
    flat = max(energies[-w - 1:]) - min(energies[-w - 1:]) <= 1e-12 * scale
    return flat and min(history[-w:]) > 0.9 * best_before


def newton(problem, z0, tolerance, max_iterations=50, avoid_saddles=False):
    """Minimise ``problem`` from ``z0`` until the gradient norm is at most ``tolerance``.

    Parameters
    ----------
    problem : object
        Provides ``value(z)`` (``inf`` where inadmissible), ``gradient(z)``,
        ``hessian(z, project)`` (CSR, free dofs) and ``energy_scale`` (J, a
        typical energy magnitude used for round-off tests); optionally
        ``pattern``, the :class:`SymmetricPattern` of its Hessians.
    z0 : (n,) array
        Admissible starting free dofs.
    tolerance : float
        Stopping tolerance on the Euclidean norm of the gradient, N.
    max_iterations : int
    avoid_saddles : bool
        If True, an exact Hessian with negative pivots (indefinite, by PARDISO's
        inertia) is not used: the step comes from the projected Hessian instead,
        whose directions lead downhill to a minimum rather than to the nearest
        stationary point. Used after a saddle was detected (see
        :func:`breastcore.saddle.escape_saddle`); without inertia (SuperLU) it
        has no effect.

    Returns
    -------
    NewtonResult
        ``success`` is False if the iteration limit was hit or no step decreased
        the energy; callers decide whether to retry (continuation) or raise.
    """
    z = np.array(z0, dtype=float)
    energy = problem.value(z)
    if not np.isfinite(energy):
        raise ValueError("Newton start is inadmissible (inverted tet or degenerate skin triangle)")
    history = []
    energies = [energy]
    projected = 0
    message = "iteration limit"
    pattern = getattr(problem, "pattern", None)                      # reuse the symbolic factorisation
    inertia = None
    for it in range(max_iterations + 1):
        g = problem.gradient(z)
        g_norm = _norm(g)
        history.append(g_norm)
        if not np.isfinite(g_norm):
            message = "non-finite gradient"
            break
        if g_norm <= tolerance:
            return NewtonResult(z, True, it, g_norm, tolerance, energy, projected, tuple(history), "converged",
                                inertia)
        if it == max_iterations:
            break
        if _stagnated(history, energies, abs(energy) + problem.energy_scale):
            message = f"stagnated: |g| at its round-off floor for {STAGNATION_WINDOW} iterations"
            break
        accepted = None
        for mode in ("exact", "project", "shift"):
            K = problem.hessian(z, project=(mode != "exact"))
            if mode == "shift":
                K = shift_diagonal(K, 1e-6 * abs(K.diagonal()).max())
            factor, d = _factor_solve(K, g, pattern)
            if mode == "exact":
                inertia = None if factor is None else factor.negative_pivots
                if avoid_saddles and inertia:
                    continue
            if d is None or _dot(g, d) >= -1e-12 * g_norm * _norm(d):
                continue
            accepted = _line_search(problem, z, d, energy, g, g_norm, expand=(mode != "exact"))
            if accepted is not None:
                projected += mode != "exact"
                break
        if accepted is None:
            message = "no descent step found (line search failed)"
            break
        step, z, energy = accepted
        energies.append(energy)
        log.debug("newton it=%d |g|=%.3e step=%.3g E=%.9e mode=%s neg=%s", it, g_norm, step, energy, mode,
                  factor.negative_pivots)
    return NewtonResult(z, False, len(history) - 1, history[-1], tolerance, energy, projected, tuple(history), message,
                        inertia)
