"""Leaving a saddle point: an equilibrium whose Hessian has negative eigenvalues.

Newton's method with the exact Hessian converges to the nearest stationary
point, which on refined meshes in the standing posture is sometimes a saddle
(1-3 negative eigenvalues, reported by PARDISO's inertia): an unstable
equilibrium, not the energy minimum the model defines. :func:`escape_saddle`
moves off it along the directions of negative curvature and minimises again
with steps that never aim at a saddle.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import scipy.sparse.linalg as spla

from breastcore.linalg.factorization import Factorization, hessian_inertia, shift_diagonal
from breastcore.nonlinear.newton import newton

log = logging.getLogger(__name__)

#: The first trial move off a saddle, as a fraction of the problem's length scale (R).
START_FRACTION = 1e-2

#: Relative tolerance of the Lanczos eigenpairs (only a direction of descent is needed).
EIGEN_TOL = 1e-4

#: Iteration cap of the last, saddle-avoiding round. Its projected Newton steps can grind
#: near a degenerate equilibrium (on a no-inverse-crime identification, 100 iterations
#: at |g| ~ 1e-7 N in each of 16 continuation halvings); on ultra-thin standing it
#: needed 20 where it converged.
AVOID_ITERATIONS = 30

#: A negative curvature above −NEUTRAL_CURVATURE × (median |diagonal| of the Hessian) is
#: treated as a zero mode and not escaped. Saddles met on the refined meshes have
#: κ/median of −1e-2 to −20; a no-inverse-crime sensitivity run on coarse met κ = −3.3e-4
#: N/m (ratio −1e-5) at every solve, whose escape releases ~4e-9 of the energy scale and
#: cost 1.2 s each time.
NEUTRAL_CURVATURE = 1e-4

#: At most this many negative-curvature directions are computed and followed per round.
MAX_DIRECTIONS = 4

#: Log-scale bisections of the decade that brackets the lowest eigenvalue.
REFINEMENTS = 3

#: Matrices up to this size are decomposed densely.
DENSE_SIZE = 200


def negative_curvature_directions(K, count, pattern=None):
    """Unit eigenvectors of the ``count`` most negative eigenvalues of ``K``.

    Parameters
    ----------
    K : (n, n) sparse symmetric matrix
    count : int
        The number of negative eigenvalues (the inertia), ≥ 1.
    pattern : SymmetricPattern, optional
        The sparsity pattern of ``K`` (diagonal included): the shifted matrices
        share it, so its symbolic analysis is reused.

    Returns
    -------
    eigenvalues : (m,) array, N/m
        The negative eigenvalues found (m ≤ ``count``; empty without inertia).
    vectors : (n, m) array

    Notes
    -----
    The negative eigenvalues need not be the ones nearest zero (a saddle of this
    energy can have κ = -3 N/m below positive ones of 0.03 N/m). By Sylvester's
    law of inertia, the negative pivots of ``K - σI`` count the eigenvalues below
    σ; σ = -d 10⁻ʲ (``d`` the largest diagonal entry) is raised, j = 0 … 12,
    while no eigenvalue lies below it, and the last decade is then bisected
    :data:`REFINEMENTS` times in log scale (σ within a factor 10^(1/8) of the
    lowest eigenvalue). Shift-invert Lanczos at that σ converges to the lowest
    ones (to the relative tolerance :data:`EIGEN_TOL`); a factorisation costs
    about ten Lanczos iterations, and the refinement saves far more.
    """
    n = K.shape[0]
    if n <= DENSE_SIZE:
        values, vectors = np.linalg.eigh(K.toarray())
        negative = values < 0.0
        return values[negative][:count], _fix_signs(vectors[:, negative][:, :count])
    scale = float(abs(K.diagonal()).max())
    sigma, factor = None, None
    for j in range(13):                            # from -d up towards zero
        trial = -scale * 10.0 ** (-j)
        shifted = Factorization(shift_diagonal(K, -trial), pattern)
        if shifted.negative_pivots is None:        # no inertia (SuperLU): cannot bracket
            return np.empty(0), np.empty((n, 0))
        if shifted.negative_pivots > 0:            # passed the lowest eigenvalue: the last σ brackets it
            break
        sigma, factor = trial, shifted
    if sigma is None:
        return np.empty(0), np.empty((n, 0))
    for k in range(1, REFINEMENTS + 1):            # bisect the decade in log scale: closer σ, faster Lanczos
        ratio = 10.0 ** (-0.5 ** k)
        shifted = Factorization(shift_diagonal(K, -sigma * ratio), pattern)
        if shifted.negative_pivots == 0:
            sigma, factor = sigma * ratio, shifted
    inverse = spla.LinearOperator((n, n), matvec=factor.solve, dtype=float)
    k = min(count, n - 2)
    # A direction of negative curvature is all that is needed: a loose tolerance will do.
    start = np.random.default_rng(0).standard_normal(n)            # ARPACK's default start is random
    values, vectors = spla.eigsh(K, k=k, sigma=sigma, which="LM", OPinv=inverse, tol=EIGEN_TOL, v0=start)
    order = np.argsort(values)
    values, vectors = values[order], vectors[:, order]
    negative = values < 0.0
    return values[negative], _fix_signs(vectors[:, negative])


def _fix_signs(vectors):
    """Eigenvectors with their largest-magnitude entry positive (a reproducible sign)."""
    rows = np.argmax(np.abs(vectors), axis=0)
    return vectors * np.sign(vectors[rows, np.arange(vectors.shape[1])])


def escape_saddle(problem, result, max_iterations=100, max_rounds=4, minimise=None):
    """Minimise again from a saddle ``result`` of :func:`~breastcore.nonlinear.newton.newton`.

    Parameters
    ----------
    problem : EquilibriumProblem-like
        ``value``, ``gradient``, ``hessian`` and ``pattern`` as for ``newton``.
    result : NewtonResult
        A converged solve with ``negative_pivots > 0``.
    max_iterations : int
        Newton iterations per round.
    max_rounds : int
        Perturb-and-minimise rounds before giving up (then ``negative_pivots`` > 0 tells).
    minimise : callable, optional
        ``minimise(problem, z0, tolerance, max_iterations, avoid_saddles)`` → NewtonResult: the solve's
        own method (default :func:`~breastcore.nonlinear.newton.newton`; the CG baseline for a CG solve).

    Returns
    -------
    NewtonResult
        Its ``iterations`` include every round's; ``negative_pivots`` is the
        inertia of the exact Hessian at the returned point. If the last round
        does not converge (within :data:`AVOID_ITERATIONS`), the equilibrium of
        the round before is returned: converged, lower in energy than ``result``,
        but still a saddle (``negative_pivots > 0``, and a warning is logged).

    Notes
    -----
    A lowest eigenvalue above ``-NEUTRAL_CURVATURE`` × the median stiffness is a
    zero mode to round-off: the result is returned as it is, its inertia recorded.
    At a saddle x* with ``K v = κ v``, κ < 0, the energy along ``x* + α v`` is
    ``J(x*) + ½ κ α² + O(α³)``. The eigenvectors of all negative eigenvalues (the
    inertia, at most :data:`MAX_DIRECTIONS`) are followed in turn, lowest first
    (:func:`_downhill_along`): along each, the step ``α`` (either sign) is the largest
    of ``α₀ 2⁻ᵏ`` with an admissible state and a lower energy, where ``α₀`` is
    :data:`START_FRACTION` × ``problem.length_scale`` (the cap radius R). Newton
    with the exact Hessian then minimises again; it may end on another saddle
    (then the next round leaves that one). The last round runs with
    ``avoid_saddles`` (modified Hessians that never aim at a saddle).
    """
    minimise = minimise or newton
    pattern = getattr(problem, "pattern", None)
    iterations = result.iterations
    length = START_FRACTION * problem.length_scale
    converged = result                              # the last equilibrium reached (lowest energy so far)
    K = problem.hessian(result.x)                   # exact Hessian at result.x
    for round_ in range(max_rounds):
        inertia = result.negative_pivots
        if not inertia or not result.success:
            break
        values, vectors = negative_curvature_directions(K, min(inertia, MAX_DIRECTIONS), pattern)
        if values.size == 0:
            log.info("saddle test: no negative eigenvalue found near zero (inertia %d)", inertia)
            break
        stiffness = float(np.median(np.abs(K.diagonal())))
        if values.min() > -NEUTRAL_CURVATURE * stiffness:
            log.info("saddle test: κ_min = %.3e N/m is a neutral direction (median stiffness %.3e N/m); kept",
                     values.min(), stiffness)
            return _with(result, iterations=iterations)
        moved, alpha = _downhill_along(problem, result.x, result.energy, vectors, length)
        if moved is None:
            log.info("saddle escape: no admissible lower-energy point along %d directions", values.size)
            break
        log.info("saddle (κ_min = %.3e N/m, inertia %d): moved %.3e m, minimising again", values.min(), inertia,
                 alpha)
        # avoid_saddles costs two factorisations per iteration: on ultra-thin standing the plain
        # rounds reach the minimum in 11 iterations where it took 20, so only the last round uses it
        last_round = round_ == max_rounds - 1
        result = minimise(problem, moved, result.tolerance,
                          min(max_iterations, AVOID_ITERATIONS) if last_round else max_iterations, last_round)
        iterations += result.iterations
        if result.success:
            K = problem.hessian(result.x)          # its inertia now, its eigenvectors next round
            result = converged = _with(result, negative_pivots=hessian_inertia(problem, result.x, K),
                                       inertia_at_x=True)
    if not result.success:          # else a continuation stalled on a hopeless escape fails after 1000s of iterations
        log.warning("saddle escape failed (%s); returning the equilibrium reached before it, a saddle with "
                    "%d negative eigenvalues", result.message, converged.negative_pivots)
        result = converged
    elif result.negative_pivots:
        log.warning("saddle escape ended on a saddle (%d negative eigenvalues)", result.negative_pivots)
    return _with(result, iterations=iterations)


def _downhill_along(problem, z, energy, vectors, length):
    """Move along each direction in turn; ``(moved, α of the first move)``, ``(None, None)`` if no move.

    Along each direction ``v`` (the columns of ``vectors``, lowest curvature first), the
    move is ``± α v`` with the largest ``α = length 2⁻ᵏ`` that lowers the energy, from
    the point the previous moves reached. Leaving along the lowest direction only,
    Newton often stops on the saddle that the others lead to, and each further round
    costs an eigen-solve: on six ultra-thin standing cold solves, following every
    direction took 17.6 s against 24.5 s, and reached the same minimum or a lower one.
    """
    moved, first = None, None
    for v in vectors.T:
        alpha = length
        while alpha > 1e-9 * length:
            trial = _lower_of(problem, z, energy, alpha * v)
            if trial is not None:
                z, energy = trial
                moved, first = z, alpha if first is None else first
                break
            alpha *= 0.5
    return moved, first


def _lower_of(problem, z, energy, step):
    """``(z ± step, its energy)`` for the first sign that lowers the energy, else None."""
    for sign in (1.0, -1.0):
        trial = z + sign * step
        e = problem.value(trial)
        if np.isfinite(e) and e < energy:
            return trial, e
    return None


def _with(result, **changes):
    return dataclasses.replace(result, **changes)
