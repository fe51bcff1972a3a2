"""Identification of ``Λ = (R, H, λ, μ, λ_s, μ_s)`` from measurements (issue #3, spec §5).

Cost: ``E(Λ) = Σ_i w_i (M_i(Λ)/M̄_i − 1)²``.

Methods
-------
``lm`` (default)
    Levenberg–Marquardt (:mod:`~breastcore.inverse.lm`) in the unconstrained variables
    of :mod:`~breastcore.inverse.transforms`.
``gauss-newton``
    The paper's method (:mod:`~breastcore.inverse.gauss_newton`).

Either is followed by the branch check (:mod:`~breastcore.inverse.branch`) when warm starts
were used. The record of a run is :class:`~breastcore.inverse.history.IdentificationResult`.
"""

from __future__ import annotations

import functools

import numpy as np

from breastcore.inverse import branch
from breastcore.inverse.gauss_newton import gauss_newton
from breastcore.inverse.history import IdentificationResult, IdentificationRun
from breastcore.inverse.lm import levenberg_marquardt
from breastcore.inverse.options import IdentificationOptions

__all__ = ["IdentificationResult", "identify", "relative_jacobian", "too_few_weighted"]

def relative_jacobian(mm, values, solutions, options, warm):
    """``∂M/∂Λ · Λ / M̄``-ready Jacobian ``∂M/∂Λ`` (posture, quantity, 6), SI.

    The forward differences' solves start from ``solutions``, which ``warm`` then
    remembers (they are where the next step starts from). The implicit Jacobian's
    ``∂x/∂Λ`` go to ``warm`` (:meth:`~breastcore.inverse.warm_start.WarmStarts.remember_tangents`),
    which uses them if it has ``tangent_starts`` and remembers ``values`` (the caller's
    ``solutions`` being the equilibria it remembers there: LM and Gauss–Newton remember them first).
    """
    if options.jacobian == "implicit":
        tangents = {}
        dM = mm.implicit_jacobian(values, solutions, tangents=tangents)
        warm.remember_tangents(values, tangents)
        return dM
    dM = mm.fd_jacobian(values, solutions, options.fd_step)
    warm.remember(solutions, values)
    return dM


class _LastJacobian:
    """:func:`relative_jacobian`, remembering its last implicit Jacobian and where it was taken.

    The final Jacobian of :func:`identify` is at LM's last accepted point, whose Jacobian
    LM has already taken (scipy's ``trf`` asks for it after each accepted step): a second
    computation would repeat it bit for bit. The finite-difference Jacobian is not kept,
    as its call also sets the warm starts.
    """

    def __init__(self):
        self.values, self.solutions, self.value = None, None, None

    def __call__(self, mm, values, solutions, options, warm):
        if options.jacobian != "implicit":
            return relative_jacobian(mm, values, solutions, options, warm)
        values = np.array(values, dtype=float)
        if solutions is not self.solutions or not np.array_equal(values, self.values):
            self.value = relative_jacobian(mm, values, solutions, options, warm)
            self.values, self.solutions = values, solutions
        return self.value.copy()


def too_few_weighted(weights, parameters) -> str | None:
    """Why the measurements of ``weights`` (posture, quantity) cannot determine ``parameters``
    parameters, with what to do; None when at least ``parameters`` of them have weight > 0."""
    weights = np.asarray(weights, float)
    weighted = int(np.count_nonzero(weights > 0))
    if weighted >= parameters:
        return None
    why = "every weight is 0" if weighted == 0 else f"only {weighted} of {weights.size} measurements have weight > 0"
    advice = ("measure at least two postures (5 measurements each)" if weights.shape[0] < 2 else
              "give weight > 0 to at least as many measurements as there are parameters")
    return f"{why}: {weighted} measurements cannot determine {parameters} parameters; {advice}"


def identify(mm, target, initial, options=IdentificationOptions(), weights=None, warm=None) -> IdentificationResult:
    """Find Λ minimising ``E`` for the measurements ``target`` (posture, quantity), SI units.

    ``warm``: the :class:`~breastcore.inverse.warm_start.WarmStarts` the first solve starts
    from (default: none, a cold solve at ``initial``); the run keeps its own afterwards.

    Raises
    ------
    SolveError
        Only if the forward solve fails at the initial guess.
    ValueError
        If fewer measurements carry weight than there are parameters (e.g. one posture's
        five for six): Λ would not be determined and its intervals would be meaningless;
        or if an initial value is not > 0 (the fit works in ln Λ and logit(H/R)).
    """
    if getattr(mm, "warm_radius", options.warm_radius) != options.warm_radius:
        raise ValueError(f"the measurement model's warm_radius ({mm.warm_radius}) is not the options' "
                         f"({options.warm_radius}): build it with MeasurementModel.from_problem")
    if getattr(mm, "reduced_snapshots", options.reduced_snapshots) != options.reduced_snapshots:
        raise ValueError(f"the measurement model's reduced_snapshots ({mm.reduced_snapshots}) is not the "
                         f"options' ({options.reduced_snapshots}): build it with MeasurementModel.from_problem")
    if getattr(mm, "tangent_starts", options.tangent_starts) != options.tangent_starts:
        raise ValueError(f"the measurement model's tangent_starts ({mm.tangent_starts}) is not the "
                         f"options' ({options.tangent_starts}): build it with MeasurementModel.from_problem")
    target = np.asarray(target, float)
    w = np.ones_like(target) if weights is None else np.asarray(weights, float)
    refusal = too_few_weighted(w, len(initial))
    if refusal:
        raise ValueError(refusal)
    if not np.all(np.asarray(initial, float) > 0):
        raise ValueError(f"initial guess {list(initial)}: every identified parameter must be > 0 (the fit works in "
                         "ln Λ and logit(H/R))")
    sqrt_w = np.sqrt(w)
    run = IdentificationRun(mm, target, w)
    implicit = options.jacobian == "implicit"
    warm = mm.warm_starts() if warm is None else warm
    solutions = mm.solve(initial, warm, jacobian=implicit)  # a failure here is the caller's to report
    warm.remember(solutions, initial)

    run.record(initial, solutions)
    jacobian = _LastJacobian()
    method = functools.partial(levenberg_marquardt if options.method == "lm" else gauss_newton,
                               jacobian=jacobian)
    method(mm, target, sqrt_w, np.asarray(initial, float), solutions, options, run, warm)
    if mm.warm_radius > 0:
        branch.check_branch(mm, target, sqrt_w, options, run, method, warm)
    forward_solves = mm.solves
    final = run.parameters[-1]
    if run.solutions is None:
        run.solutions = mm.solve(final, warm)
        warm.remember(run.solutions, final)
    dM = jacobian(mm, final, run.solutions, options, warm)
    return run.result(dM * np.asarray(final)[None, None, :] / target[..., None], forward_solves)
