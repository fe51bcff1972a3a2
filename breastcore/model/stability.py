"""Warnings for equilibria a breast cannot hold: saddles, and stretches beyond any soft tissue.

A forward solve converges to its gradient tolerance and then checks the inertia of the exact
Hessian; a saddle the escape cannot leave (:func:`breastcore.nonlinear.saddle.escape_saddle`) is
returned with its count of negative eigenvalues. Very soft parameters can also reach stable
shapes that no tissue survives (a stretch of 300, a node kilometres away). Both are results of
the discrete model, not errors of the solver, so they are returned, and these warnings travel
with them (the dataset's ``regime_warning``, ``show``, the command line, the job log).
"""

from __future__ import annotations

#: Largest principal stretch above which a shape is beyond soft tissue (it tears well below 5;
#: the paper's Λ̄ reaches 2.5 standing on the reference mesh, its crushed back layer aside).
MAX_PLAUSIBLE_STRETCH = 5.0


def saddle_warning(negative_eigenvalues) -> str:
    """One line naming the postures whose equilibrium is a saddle, else ``""``.

    ``negative_eigenvalues``: posture name to the exact Hessian's count at the shape (0 a stable
    minimum; -1 unknown, without PARDISO's inertia, and not warned).
    """
    saddles = {name: n for name, n in negative_eigenvalues.items() if n > 0}
    if not saddles:
        return ""
    listed = ", ".join(f"{name} ({n} negative eigenvalue{'s' if n > 1 else ''})" for name, n in saddles.items())
    return (f"unstable equilibrium, a saddle of the energy, in {listed}: the solver's saddle escape could not "
            "leave it, and no breast holds such a shape")


def postures_over(values, limit, shown) -> str:
    """``"standing 318, bent45 nan"``: each posture whose value is not ``<= limit`` (NaN included),
    its value formatted by ``shown``; ``""`` if none."""
    return ", ".join(f"{name} {shown(v) if v == v else 'not finite'}" for name, v in values.items()
                     if not v <= limit)


def stretch_warning(max_stretch) -> str:
    """One line naming the postures whose largest stretch exceeds :data:`MAX_PLAUSIBLE_STRETCH`, else ``""``."""
    listed = postures_over(max_stretch, MAX_PLAUSIBLE_STRETCH, lambda s: f"{s:.3g}")
    if not listed:
        return ""
    return (f"largest principal stretch above {MAX_PLAUSIBLE_STRETCH:g} ({listed}): beyond any soft tissue, "
            "the parameters are outside the model's physical range")
