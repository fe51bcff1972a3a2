"""The computations of the Chassaignac calibration scene (issue #18): cold solves and the uniqueness probe.

Two jobs per value of the coefficient ``c`` feed the scene
(:mod:`breastcore.report.calibration` plans them and reads them back):

- :func:`level_points_dataset`, on one mesh level: cold solves of every posture at
  the truth Λ̄ and at the corners of the parameter box, each recording its 15
  measurements, min det F and solver diagnostics (or the typed ``SolveError``'s),
  plus the relative Jacobian at Λ̄;
- :func:`uniqueness_dataset`, on the probe level: cold solves at ``Λ (1 ± ε e_j)``
  for each parameter, whose second differences tell a smooth ``M(Λ)`` from a jump
  between equilibrium branches.

Every solve is cold, on the level's fixed-topology mesh moved by the smooth map to
the point's ``(R, H)``: the equilibria that identification defines ``M(Λ)`` by. A solve
that fails is recorded with its outcome and message; neither job raises on one.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import xarray as xr

from breastcore.forward.model import ForwardModel
from breastcore.forward.records import SolveError
from breastcore.inverse.measurements import QUANTITIES, UNITS, measure
from breastcore.inverse.operator import MeasurementModel
from breastcore.io.datasets import PARAMETER_UNIT_LIST, QUANTITY_UNIT_LIST, _var, provenance
from breastcore.model.parameters import IDENTIFIED, PARAMETER_INFO, ParameterError, Parameters
from breastcore.problem import ProblemSpec

log = logging.getLogger(__name__)

#: How one cold solve of one posture at one point ended.
OUTCOMES = ("converged", "solve_error", "inadmissible", "crash")
#: Diagnostics recorded per solve: name -> (units, long name). A failed solve records
#: those its SolveError carries (the rest NaN); an inadmissible point none.
RECORDS = {
    "min_det_F": ("1", "smallest det F over the tetrahedra (of a failed solve: at its last admissible iterate)"),
    "max_stretch": ("1", "largest principal stretch over the tetrahedra"),
    "torso_penetration": ("m", "largest depth of a node behind the torso plane y = 0 (0: none)"),
    "iterations": ("1", "minimiser iterations over all continuation steps"),
    "continuation_steps": ("1", "continuation steps (gravity ramp and δ decrease)"),
    "gradient_norm": ("N", "free-dof gradient norm reached"),
    "tolerance": ("N", "stopping tolerance: rtol × gravity load norm"),
    "energy": ("J", "discrete energy J_h at the solution"),
    "negative_eigenvalues": ("1", "negative eigenvalues of the exact Hessian at the solution (0: a stable "
                                  "minimum; -1: unknown)"),
    "load_factor": ("1", "gravity fraction reached by the continuation (1 when converged)"),
    "smoothing_reached": ("m", "Chassaignac smoothing δ reached by the continuation"),
    "wall_time": ("s", "wall time of the cold solve"),
}


def cold_solve(model: ForwardModel, params, posture, measurement_set="paper15"):
    """One cold solve, measured; never raises.

    Parameters
    ----------
    model : ForwardModel
    params : Parameters or ParameterError
        The point; a ParameterError (an inadmissible point, e.g. ``H ≥ R``) is recorded
        as the outcome ``inadmissible`` without a solve.
    posture : Posture
    measurement_set : {"paper15", "exact"}

    Returns
    -------
    outcome : str
        One of :data:`OUTCOMES`.
    record : dict
        :data:`RECORDS` values (NaN where unknown).
    values : ndarray, shape (5,)
        The measurements in :data:`~breastcore.inverse.measurements.QUANTITIES` order (SI), NaN
        unless converged.
    message : str
        The failure's diagnostics ("" when converged).
    solution : PostureSolution or None
    """
    record = dict.fromkeys(RECORDS, np.nan)
    values = np.full(len(QUANTITIES), np.nan)
    if isinstance(params, ParameterError):
        return "inadmissible", record, values, str(params), None
    tic = time.perf_counter()
    try:
        solution = model.solve(params, posture)
    except SolveError as err:
        record.update(min_det_F=err.min_det_F, iterations=err.iterations, gradient_norm=err.gradient_norm,
                      tolerance=err.tolerance, load_factor=err.load_factor, smoothing_reached=err.smoothing,
                      wall_time=time.perf_counter() - tic)
        return "solve_error", record, values, str(err), None
    except Exception as err:  # noqa: BLE001 — the job records every point, whatever happens to one
        record["wall_time"] = time.perf_counter() - tic
        return "crash", record, values, f"{type(err).__name__}: {err}", None
    record.update(min_det_F=solution.min_det_F, max_stretch=solution.max_stretch,
                  torso_penetration=solution.torso_penetration, iterations=solution.iterations,
                  continuation_steps=solution.continuation_steps, gradient_norm=solution.gradient_norm,
                  tolerance=solution.tolerance, energy=solution.energy,
                  negative_eigenvalues=solution.negative_eigenvalues, load_factor=1.0,
                  smoothing_reached=params.smoothing, wall_time=solution.wall_time)
    measured = measure(model.mesh, solution.position, measurement_set)
    values = np.array([measured[q] for q in QUANTITIES])
    return "converged", record, values, "", solution


def point_parameters(constants, point):
    """``Parameters`` of the constants with the point's Λ, or the ParameterError that refuses it."""
    try:
        return Parameters(**{**constants, **point})
    except ParameterError as err:
        return err


def first_point(params, label):
    """The first point's ``Parameters`` (the truth Λ̄, which a dataset's problem spec holds).

    Raises the point's ParameterError, naming it, when it is not admissible: the
    dataset's ``problem`` would otherwise hold some other Λ.
    """
    if isinstance(params[0], ParameterError):
        raise ParameterError(f"the first point, {label}, is not admissible: {params[0]}") from params[0]
    return params[0]


def _stage_attrs(stage, base, model, postures, measurement_set, config_hash, **attrs) -> dict:
    """Provenance of a ``stage`` dataset at the point ``base``, with the problem spec it was solved with."""
    problem = ProblemSpec(parameters=base, solver=model.options, postures=tuple(postures),
                          measurement_set=measurement_set)
    return provenance(stage, base, config_hash, **attrs, **problem.attrs())


def solve_set(model, points, postures, measurement_set, label=""):
    """Cold solves of every posture at every point (``Parameters`` or ``ParameterError``).

    Returns a dict of arrays over ``(point, posture)``: ``outcome``, ``message``, each
    :data:`RECORDS` entry, and ``measurement`` over ``(point, posture, quantity)``;
    ``solutions``, the first point's ``{posture name: PostureSolution}`` (None unless
    every posture converged there).
    """
    shape = (len(points), len(postures))
    out = {"outcome": np.empty(shape, dtype=object), "message": np.empty(shape, dtype=object),
           "measurement": np.full(shape + (len(QUANTITIES),), np.nan), **{k: np.full(shape, np.nan) for k in RECORDS}}
    first = {}
    for i, params in enumerate(points):
        for k, posture in enumerate(postures):
            outcome, record, values, message, solution = cold_solve(model, params, posture, measurement_set)
            out["outcome"][i, k], out["message"][i, k], out["measurement"][i, k] = outcome, message, values
            for name, value in record.items():
                out[name][i, k] = value
            log.info("%s point %d/%d, %s: %s in %.2f s, min det F %.3g %s", label, i + 1, len(points), posture.name,
                     outcome, record["wall_time"], record["min_det_F"], message)
            if i == 0 and solution is not None:
                first[posture.name] = solution
    out["solutions"] = first if len(first) == len(postures) else None
    return out


def relative_jacobian(model, params, postures, measurement_set, solutions, values):
    """``∂ln M/∂ln Λ`` at converged ``solutions``, shape ``(posture, quantity, parameter)``, and its singular values.

    Notes
    -----
    :meth:`~breastcore.inverse.operator.MeasurementModel.implicit_jacobian` gives
    ``∂M_i/∂Λ_j`` from one back-substitution per parameter with the factorised
    exact Hessian, ``du/dΛ = −K⁻¹ ∂g/∂Λ``; scaling by ``Λ_j / M_i`` makes it
    dimensionless, ``J_ij = (Λ_j/M_i) ∂M_i/∂Λ_j``. The singular values
    ``σ_1 ≥ … ≥ σ_6`` of the 15×6 matrix measure how well the 15 measurements
    determine the six parameters: ``σ_6`` near 0 is a direction of Λ that the
    measurements barely see.
    """
    mm = MeasurementModel(model, params, postures, measurement_set)
    at = np.array(params.identified())
    J = mm.implicit_jacobian(at, solutions)
    rel = J * at[None, None, :] / values[..., None]
    return rel, np.linalg.svd(rel.reshape(-1, len(IDENTIFIED)), compute_uv=False)


def _coords(postures, extra=None):
    coords = {
        "posture": _var(("posture",), np.array([p.name for p in postures]), "1", "posture name"),
        "posture_angle": _var(("posture",), np.array([p.angle for p in postures], float), "degree",
                              "forward-bend angle θ"),
        "quantity": _var(("quantity",), np.array(QUANTITIES), "1", "measured quantity"),
        "quantity_units": _var(("quantity",), np.array([UNITS[q] for q in QUANTITIES]), "1", "unit of each quantity"),
        "parameter": _var(("parameter",), np.array(IDENTIFIED), "1", "identified parameter"),
        "parameter_units": _var(("parameter",), np.array([PARAMETER_INFO[p].units for p in IDENTIFIED]), "1",
                                "unit of each parameter"),
    }
    coords.update(extra or {})
    return coords


def _record_variables(solved, dims, what):
    data = {"outcome": _var(dims, solved["outcome"].astype(str), "1", f"{what}: one of {', '.join(OUTCOMES)}"),
            "message": _var(dims, solved["message"].astype(str), "1", f"{what}: failure diagnostics (empty when "
                                                                       "converged)"),
            "converged": _var(dims, (solved["outcome"] == "converged").astype(np.int8), "1",
                              f"{what}: 1 where the cold solve converged")}
    for name, (units, long_name) in RECORDS.items():
        data[name] = _var(dims, solved[name], units, f"{what}: {long_name}")
    return data


def level_points_dataset(model, level, labels, points, constants, postures, measurement_set="paper15",
                         config_hash=None) -> xr.Dataset:
    """Cold solves of every posture at every point on one level, and the relative Jacobian at the first point.

    Parameters
    ----------
    model : ForwardModel
        On the level's fixed-topology mesh (the map moves it to each point's R, H).
    level : str
    labels : sequence of str
        One label per point; the first point is the truth Λ̄, where the Jacobian is taken.
    points : sequence of dict
        The six identified parameters of each point (SI).
    constants : dict
        The non-identified parameters (ρ, g, c, δ, t_s, θ_D).
    postures : sequence of Posture
    measurement_set : {"paper15", "exact"}
    config_hash : str, optional

    Returns
    -------
    xarray.Dataset
        Stage ``calibrate``: over ``(point, posture)`` the outcome, message and
        :data:`RECORDS`, over ``(point, posture, quantity)`` the measurements (NaN
        unless converged); ``relative_jacobian`` and ``singular_value`` at the first
        point (NaN unless every posture converged there).

    Raises
    ------
    ParameterError
        If the first point is not admissible (before any solve); other points that are
        not are recorded as ``inadmissible``.
    """
    params = [point_parameters(constants, p) for p in points]
    base = first_point(params, labels[0])
    solved = solve_set(model, params, postures, measurement_set, label=f"{level} c={constants['chassaignac']:g} Pa")
    rel = np.full((len(postures), len(QUANTITIES), len(IDENTIFIED)), np.nan)
    singular = np.full(len(IDENTIFIED), np.nan)
    if solved["solutions"] is not None:
        try:
            rel, singular = relative_jacobian(model, params[0], postures, measurement_set, solved["solutions"],
                                              solved["measurement"][0])
        except Exception as err:  # noqa: BLE001 — recorded as NaN: the solves stay usable
            log.warning("relative Jacobian at %s failed: %s: %s", labels[0], type(err).__name__, err)
    data = {
        "point_parameters": _var(("point", "parameter"), np.array([[p[k] for k in IDENTIFIED] for p in points], float),
                                 PARAMETER_UNIT_LIST, "Λ of the point; units per parameter in parameter_units"),
        "measurement": _var(("point", "posture", "quantity"), solved["measurement"], QUANTITY_UNIT_LIST,
                            "the point's measurements from the cold solve (NaN unless converged); units per "
                            "quantity in quantity_units"),
        **_record_variables(solved, ("point", "posture"), "solve of the point"),
        "relative_jacobian": _var(("posture", "quantity", "parameter"), rel, "1",
                                  f"relative Jacobian ∂ln M/∂ln Λ at the point {labels[0]} (implicit; NaN unless every "
                                  "posture converged)"),
        "singular_value": _var(("singular",), singular, "1",
                               f"singular values of the relative Jacobian at the point {labels[0]}, largest first"),
    }
    coords = _coords(postures, {"point": _var(("point",), np.array(labels), "1", "point label (truth or box corner)")})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs = _stage_attrs("calibrate", base, model, postures, measurement_set, config_hash, mesh_level=level,
                            chassaignac=float(constants["chassaignac"]), jacobian_point=labels[0],
                            title="calibration of the Chassaignac coefficient: cold solves on one level for one c "
                                  "(mesh_level, chassaignac)")
    return ds


def nonlinearity(base, minus, plus):
    r"""Relative second difference of ``M`` per parameter, and the relative first difference.

    Parameters
    ----------
    base : ndarray, shape (m,)
        ``M(Λ)``.
    minus, plus : ndarray, shape (p, m)
        ``M(Λ (1 − ε e_j))`` and ``M(Λ (1 + ε e_j))`` for each parameter ``j``.

    Returns
    -------
    second, first : ndarray, shape (p,)
        NaN for a parameter whose solves did not all converge.

    Notes
    -----
    .. math:: N_j = \max_i \frac{|(M_i^+ - M_i^0) - (M_i^0 - M_i^-)|}{|M_i^0|},
              \qquad D_j = \max_i \frac{|M_i^+ - M_i^-|}{2 |M_i^0|}.

    For a smooth ``M``, ``N_j = O(ε²)`` (the second derivative times ε²) and
    ``D_j = O(ε)`` (the relative Jacobian times ε). A cold solve that lands on
    another equilibrium branch on one side moves ``M`` by 1e-4–1e-3 relative, which
    makes ``N_j`` of that size however small ε is.
    """
    base, minus, plus = (np.asarray(a, float) for a in (base, minus, plus))
    second = np.max(np.abs((plus - base) - (base - minus)) / np.abs(base), axis=-1)
    first = np.max(np.abs(plus - minus) / (2.0 * np.abs(base)), axis=-1)
    return second, first


SIDES = ("minus", "plus")


def uniqueness_dataset(model, level, truth, constants, postures, measurement_set="paper15", epsilon=1e-6,
                       config_hash=None) -> xr.Dataset:
    """The uniqueness probe: cold solves at ``Λ̄`` and at ``Λ̄ (1 ± ε e_j)`` for each of the six parameters.

    Parameters
    ----------
    model : ForwardModel
    level : str
    truth : dict
        Λ̄, the six identified parameters (SI).
    constants : dict
        ρ, g, c, δ, t_s, θ_D.
    postures : sequence of Posture
    measurement_set : {"paper15", "exact"}
    epsilon : float
        Relative step ε.
    config_hash : str, optional

    Returns
    -------
    xarray.Dataset
        Stage ``uniqueness``: the measurements and solve records at Λ̄ (``*_base``)
        and at each shifted point (``(parameter, side)``), and per parameter
        ``nonlinearity`` and ``first_difference`` (:func:`nonlinearity`). The
        threshold that calls a parameter "linear" is the scene's, applied by its
        summary, so that changing it reruns no solve.

    Raises
    ------
    ParameterError
        If Λ̄ is not admissible (before any solve).
    """
    values = np.array([truth[k] for k in IDENTIFIED], float)
    shifted = []
    for j in range(len(IDENTIFIED)):
        for sign in (-1.0, 1.0):
            v = values.copy()
            v[j] *= 1.0 + sign * epsilon
            shifted.append(dict(zip(IDENTIFIED, v.tolist())))
    points = [dict(zip(IDENTIFIED, values.tolist()))] + shifted
    params = [point_parameters(constants, p) for p in points]
    base = first_point(params, "the truth")
    solved = solve_set(model, params, postures, measurement_set,
                       label=f"uniqueness {level} c={constants['chassaignac']:g} Pa")
    m = solved["measurement"].reshape(len(points), -1)                       # (point, 15)
    minus, plus = m[1::2], m[2::2]
    second, first = nonlinearity(m[0], minus, plus)
    p = len(IDENTIFIED)

    def split(array):                                                         # (point, ...) -> base, (p, side, ...)
        return array[0], array[1:].reshape((p, 2) + array.shape[1:])

    base_value, shifted_value = split(solved["measurement"])
    data = {"measurement_base": _var(("posture", "quantity"), base_value, QUANTITY_UNIT_LIST,
                                     "measurements at Λ̄ (cold; NaN unless converged); units in quantity_units"),
            "measurement_shifted": _var(("parameter", "side", "posture", "quantity"), shifted_value, QUANTITY_UNIT_LIST,
                                        "measurements at Λ̄ (1 ± ε e_j) (cold; NaN unless converged); units in "
                                        "quantity_units")}
    names = ("outcome", "message", *RECORDS)
    for suffix, index, dims, what in (("base", 0, ("posture",), "solve at Λ̄"),
                                      ("shifted", 1, ("parameter", "side", "posture"), "solve at Λ̄ (1 ± ε e_j)")):
        records = {name: split(solved[name])[index] for name in names}
        for name, var in _record_variables(records, dims, what).items():
            data[f"{name}_{suffix}"] = var
    data["nonlinearity"] = _var(("parameter",), second, "1",
                                "max_i |(M_i(+) − M_i(0)) − (M_i(0) − M_i(−))| / |M_i(0)| over the measurements "
                                "(NaN unless all three solves converged)")
    data["first_difference"] = _var(("parameter",), first, "1", "max_i |M_i(+) − M_i(−)| / (2 |M_i(0)|)")
    coords = _coords(postures, {"side": _var(("side",), np.array(SIDES), "1", "sign of the shift ±ε e_j")})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs = _stage_attrs("uniqueness", base, model, postures, measurement_set, config_hash, mesh_level=level,
                            epsilon=float(epsilon), chassaignac=float(constants["chassaignac"]),
                            title="uniqueness probe of M(Λ): cold solves at Λ̄ (1 ± ε e_j) on one level for one c "
                                  "(mesh_level, chassaignac, epsilon)")
    return ds
