"""A start for a far forward solve: the energy minimised over the span of earlier displacements.

Warm starts from a solved state pay only within a few per cent of its Λ (``docs/benchmarks.md``,
"Warm starts against distance"). Farther, this predictor minimises the same energy ``J_h``
at the new Λ over a reduced space, ``x(a) = X(R, H) + Σ_i a_i u_i``, where the ``u_i`` are
the displacements of equilibria already solved at other Λ (a Galerkin reduced-order
model with the job's own solves as snapshots). Its Newton steps need the full Hessian only
as ``Bᵀ K B``, with no large factorisation; the full Newton solve then starts from its
minimiser.
"""

from __future__ import annotations

import numpy as np

#: Reduced Newton iterations at most; the predictor only has to come close.
MAX_ITERATIONS = 30
#: Stop when the reduced gradient falls below this fraction of the full one (relative).
REDUCED_RTOL = 1e-6


def reduced_start(model, params, posture, displacements, max_iterations=MAX_ITERATIONS):
    """Minimise ``J_h`` at ``params`` over ``X(R, H) + span(displacements)``.

    Parameters
    ----------
    model : ForwardModel
    params : Parameters
    posture : Posture
    displacements : sequence of (N, 3) arrays, m
        Displacements ``x − X`` of equilibria at other parameters, on the same mesh.

    Returns
    -------
    (N, 3) array or None
        Node positions (m) at the reduced minimiser; None when no reduced step lowered the
        energy below that of the reference state.

    Notes
    -----
    With ``B`` the orthonormalised free-dof parts of the displacements, each iteration takes
    ``da = −(Bᵀ K B)⁺ Bᵀ g`` (the reduced Hessian's eigenvalues floored at 1e-8 of the largest,
    so that the step descends), halved until the energy falls. The fixed fold dofs and the
    back nodes' normal dofs are zero in every displacement, so ``x(a)`` satisfies the
    constraints.
    """
    problem = model.problem(params, posture)
    basis = np.column_stack([problem.free(u) for u in displacements])          # free() is a linear restriction
    basis, singular, _ = np.linalg.svd(basis, full_matrices=False)
    basis = basis[:, singular > 1e-10 * singular.max()]
    z0 = problem.free(problem.reference)
    a = np.zeros(basis.shape[1])
    energy = problem.value(z0)
    moved = False
    for _ in range(max_iterations):
        z = z0 + basis @ a
        g = problem.gradient(z)
        reduced_g = basis.T @ g
        if np.linalg.norm(reduced_g) <= REDUCED_RTOL * np.linalg.norm(g):
            break
        K = problem.hessian(z)
        w, V = np.linalg.eigh(basis.T @ (K @ basis))
        w = np.maximum(w, 1e-8 * np.abs(w).max())
        da = -(V @ ((V.T @ reduced_g) / w))
        step = 1.0
        while step > 1e-6:
            trial = problem.value(z0 + basis @ (a + step * da))
            if np.isfinite(trial) and trial < energy:
                break
            step *= 0.5
        else:
            break
        a, energy, moved = a + step * da, trial, True
    return problem.full(z0 + basis @ a) if moved else None
