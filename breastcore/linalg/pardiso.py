"""MKL PARDISO through ``ctypes``: one handle per sparsity pattern, its symbolic analysis reused.

Importing this module changes nothing in the process: the MKL library is loaded, and its
thread count set, when the first handle is made. ``available()`` says whether PARDISO is
installed (MKL is x86-64 only; elsewhere :mod:`breastcore.linalg.factorization` uses SuperLU).
"""

from __future__ import annotations

import ctypes
import functools
import importlib.util
import os

import numpy as np


@functools.cache
def available() -> bool:
    """Whether MKL PARDISO (through ``pypardiso``) is installed and its MKL loads (x86-64 only: SuperLU otherwise).

    Imports ``pypardiso`` (0.25 s) on the first call, which only a factorisation makes.
    """
    if importlib.util.find_spec("pypardiso") is None:
        return False
    try:
        _mkl_runtime_name()
    except (ImportError, OSError):             # installed, but its MKL runtime does not load
        return False
    return True


def _mkl_runtime_name() -> str:
    """The MKL runtime that ``pypardiso`` ships, imported only when a factorisation needs it (0.25 s)."""
    import pypardiso
    return pypardiso.ps.libmkl._name


#: Threads PARDISO may use (environment variable ``BREASTCORE_PARDISO_THREADS``, default 1).
#: On this project's 2-core machines two solves (or a solve and another job) often run at
#: once; a 2-thread PARDISO then waits for a busy core and a 25 ms factorisation takes
#: 60-200 ms, a solve 40-160 ms instead of 2 ms (measured, see docs/benchmarks.md). Forked
#: workers (postures or re-identifications in several processes) run on one thread whatever it
#: says (:func:`one_thread_in_forked_worker`).
PARDISO_THREADS_ENV = "BREASTCORE_PARDISO_THREADS"


_MKL_DOMAIN_PARDISO = 4                                              # mkl_service.h


def _set_pardiso_threads(lib) -> int:
    """Set MKL's thread count from :data:`PARDISO_THREADS_ENV`; the count set (0: the runtime's default kept)."""
    try:
        threads = int(os.environ.get(PARDISO_THREADS_ENV, "1"))
    except ValueError:
        threads = 1
    if threads > 0:
        try:                                                         # MKL serves only PARDISO here (numpy
            lib.MKL_Set_Num_Threads.argtypes = [ctypes.c_int]        # has its own BLAS)
            lib.MKL_Set_Num_Threads(threads)
        except AttributeError:                                       # not an MKL runtime: keep its default
            return 0
        try:                                                         # a PARDISO domain setting (environment
            lib.MKL_Domain_Set_Num_Threads.argtypes = [ctypes.c_int, ctypes.c_int]   # MKL_DOMAIN_NUM_THREADS)
            lib.MKL_Domain_Set_Num_Threads(threads, _MKL_DOMAIN_PARDISO)            # would override the call above
        except AttributeError:
            pass
    return max(threads, 0)


class _Pardiso:
    """One MKL PARDISO instance for a real symmetric indefinite matrix (``mtype = -2``).

    Called through ``ctypes`` on the MKL that ``pypardiso`` ships, with PARDISO's
    default ``iparm`` (as ``pypardiso`` uses it). The phases are split so that the
    symbolic analysis (phase 11: fill-reducing ordering) is done once per sparsity
    pattern and each new matrix only needs the numeric factorisation (phase 22).
    """

    _function = None
    _library = None
    _threads = 0                                 # the thread count breastcore set for PARDISO (0: MKL's default)

    def __init__(self, n, ia, ja, single=False):
        if _Pardiso._function is None:
            lib = ctypes.CDLL(os.environ.get("PYPARDISO_MKL_RT") or _mkl_runtime_name())   # read, never set
            _Pardiso._threads = _set_pardiso_threads(lib)
            _Pardiso._library = lib
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
        self.numeric = False                                         # whether L and U may be allocated
        self.owner = None                                            # token of the factor held now
        self.threads = None                                          # _threads at the analysis

    def _forget_if_threads_changed(self):
        """Forget an analysis (and factor) made on another thread count, without calling PARDISO on it.

        PARDISO may not change its thread count between phases: a factorisation (phase 22) on a
        handle analysed with 2 threads segfaults with 1 (MKL 2026.2). That happens in a worker
        forked from a process that used 2 (:func:`one_thread_in_forked_worker`). The inherited
        memory is the parent's copy: it is left, not freed, and the analysis is redone here.
        """
        if self.analysed and self.threads != _Pardiso._threads:
            self.pt[:] = 0
            self.analysed = self.numeric = False
            self.owner = None

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

    def analyse(self):
        """The symbolic analysis (phase 11) now, if not done yet.

        With ``mtype = −2`` and no scaling or weighted matching (``iparm[10] = iparm[12] = 0``,
        PARDISO's defaults for symmetric matrices, kept here) the analysis reads the pattern only,
        so zeros stand in for the values: the factors that follow are those of an analysis at the
        first factorisation, bit for bit (``tests/linalg/test_factorization.py``).
        """
        self._forget_if_threads_changed()
        if not self.analysed:
            self._call(11, np.zeros(len(self.ja), dtype=self.dtype))
            self.analysed, self.threads = True, _Pardiso._threads

    def factorize(self, data, owner):
        """Numeric factorisation of the matrix with upper-triangle values ``data``."""
        self.owner = None
        self._forget_if_threads_changed()
        if not self.analysed:
            self._call(11, data)
            self.analysed, self.threads = True, _Pardiso._threads
        self.numeric = True                                          # phase 22 may allocate even if it fails
        self._call(22, data)
        self.owner = owner
        return int(self.iparm[22])                                   # number of negative pivots

    def release_factor(self):
        """Free the numeric factor (PARDISO phase 0), keeping the symbolic analysis; a no-op if none is held.

        A numeric factorisation (phase 22) may follow without a new analysis: checked on MKL 2026.2
        (``tests/linalg/test_factorization.py``); MKL's documentation does not say so.
        """
        self._forget_if_threads_changed()
        if self.numeric:
            self.owner, self.numeric = None, False
            self._call(0, None)

    def holds(self, owner) -> bool:
        """Whether the numeric factor held now is ``owner``'s (and was made on this thread count)."""
        self._forget_if_threads_changed()
        return self.owner is not None and self.owner == owner

    def solve(self, data, b):
        self._forget_if_threads_changed()
        if not self.numeric:                                         # a forgotten or freed factor: phase 33
            raise RuntimeError("PARDISO solve without a numeric factor")   # would read no memory of ours
        b = np.asfortranarray(b, dtype=self.dtype)
        nrhs = 1 if b.ndim == 1 else b.shape[1]
        return np.ascontiguousarray(self._call(33, data, b, nrhs))

    def free(self):
        self._forget_if_threads_changed()
        if self.analysed and self._function is not None:
            try:
                self._call(-1, None)
            except Exception:                                        # noqa: BLE001 - interpreter shutdown
                pass
            self.analysed = self.numeric = False

    def __del__(self):
        self.free()


class SymmetricPattern:
    """The fixed sparsity pattern of a symmetric CSR matrix, with one reusable PARDISO handle.

    A Newton solve factorises a matrix of the same pattern at every iteration; this
    object keeps the PARDISO symbolic analysis (ordering) of that pattern, so that
    :class:`Factorization` only does the numeric phase. The handle holds one numeric
    factor at a time: a :class:`Factorization` whose factor was replaced by a later
    one refactorises itself on its next ``solve`` (results never mix). Its two handles
    (single and double precision) hold one between them (:meth:`handle_to_factorize`).

    Parameters
    ----------
    indptr, indices : int arrays
        CSR structure (sorted column indices) of the full symmetric matrix.
    n : int
        Matrix size.

    Attributes
    ----------
    mixed_min_dofs : int or None
        Matrices of this pattern with at least this many rows are factorised in single
        precision (:class:`~breastcore.linalg.factorization.Factorization`); None: the
        module default ``MIXED_PRECISION_MIN_DOFS``. Set by the forward model from
        ``SolverOptions.mixed_precision_min_dofs``.
    """

    def __init__(self, indptr, indices, n):
        self.mixed_min_dofs = None
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

    def sibling(self) -> "SymmetricPattern":
        """The same pattern with PARDISO handles of its own, so that a factor held there survives
        factorisations of this pattern's (e.g. one per posture: a posture's last factor is
        still there when its Jacobian asks for it)."""
        twin = object.__new__(SymmetricPattern)
        twin.__dict__.update(self.__dict__)
        twin._handles = {}
        return twin

    def matches(self, K):
        return (K.shape == (self.n, self.n) and K.format == "csr" and K.has_sorted_indices
                and (K.indptr is self.indptr or np.array_equal(K.indptr, self.indptr))
                and (K.indices is self.indices or np.array_equal(K.indices, self.indices)))

    def handle(self, single=False):
        """The PARDISO handle of this pattern (a separate one for single precision)."""
        if single not in self._handles:
            self._handles[single] = _Pardiso(self.n, self.ia, self.ja, single)
        return self._handles[single]

    def analyse(self, single=False):
        """Do the symbolic analysis of :meth:`handle` now (e.g. before forking workers, which then
        inherit it instead of each making their own; on more than one thread they make their own anyway:
        :func:`one_thread_in_forked_worker`)."""
        self.handle(single).analyse()

    def handle_to_factorize(self, single=False):
        """:meth:`handle`, with the other precision's numeric factor freed first: one numeric factor
        of this pattern in memory at a time.

        A single-precision factor whose refinement stalls is redone in double
        (:class:`~breastcore.linalg.factorization.Factorization`); without this, the double factor
        and the next iteration's single one were both held to the end of the solve. A cold fine50k
        standing solve with 2 PARDISO threads, where that happened, peaked at 2.7 GB (1.5 GB where it
        did not); with this, 2.1 GB, the double factor being twice the single one's size
        (docs/benchmarks.md). A factor freed so is redone from its own matrix if it is solved with again.
        """
        other = self._handles.get(not single)
        if other is not None:
            other.release_factor()
        return self.handle(single)

    def release_factors(self):
        """Free the numeric factors of this pattern's handles, keeping their symbolic analyses."""
        for handle in self._handles.values():
            handle.release_factor()

    def release(self):
        """Free PARDISO's memory for this pattern (it is re-analysed on next use)."""
        for handle in self._handles.values():
            handle.free()
        self._handles = {}


def one_thread_in_forked_worker():
    """Make PARDISO single-threaded in this process, a worker forked from one that may have used it.

    MKL here may run on GNU OpenMP (``libmkl_gnu_thread``, chosen when another library has loaded
    ``libgomp``), whose thread pool does not survive ``fork``: a forked child's first multi-threaded
    factorisation waits for ever for threads that were not copied (seen with
    ``BREASTCORE_PARDISO_THREADS=2`` and the postures in two processes). One thread per worker is
    also what two workers on two cores want.
    """
    os.environ[PARDISO_THREADS_ENV] = "1"
    if _Pardiso._library is not None:
        _Pardiso._threads = _set_pardiso_threads(_Pardiso._library)
