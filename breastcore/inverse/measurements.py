"""The five measurements of a deformed breast in one posture (spec §4).

Everything is in SI units in the torso frame (``y`` anterior, ``z`` superior).
Each measurement is a smooth function of the node positions: extremes use a
log-sum-exp smooth maximum (:func:`smooth_max`), so no value jumps when the
extreme node changes. ``docs/measurements.md`` explains the clinical side.
"""

from __future__ import annotations

import math
from types import MappingProxyType

import numpy as np

#: The five quantities measured per posture, in this fixed order.
QUANTITIES = ("volume", "area", "height", "frontal_depth", "back_depth")
#: SI unit of each quantity.
UNITS = MappingProxyType({"volume": "m3", "area": "m2", "height": "m", "frontal_depth": "m", "back_depth": "m"})
#: Long names of the quantities.
LONG_NAMES = MappingProxyType({
    "volume": "breast volume",
    "area": "skin surface area",
    "height": "breast height Δh (torso-aligned bounding box)",
    "frontal_depth": "frontal depth Δf (most frontal point from the chest wall)",
    "back_depth": "back depth Δb (nipple projection MP)",
})
#: ``paper15``: Qiao volume and straight-radii area (tape and ruler);
#: ``exact``: mesh volume and skin area (3D scan).
MEASUREMENT_SETS = ("paper15", "exact")
#: Tape radius -> rim landmark at the end of its meridian.
RADII = MappingProxyType({"TR": "S", "IR": "I", "MR": "M", "LR": "L"})
#: Default smoothing length ℓ as a fraction of the mean deformed skin edge length.
SMOOTHING_FRACTION = 0.01


class MeasurementError(ValueError):
    """Invalid measurement input; the message names the offending item."""


def check_measurement_set(name) -> str:
    """Return ``name`` if it is one of :data:`MEASUREMENT_SETS`, else raise :class:`MeasurementError`."""
    if not isinstance(name, str) or name not in MEASUREMENT_SETS:
        raise MeasurementError(f"unknown measurement set {name!r}; valid: {', '.join(MEASUREMENT_SETS)}")
    return name


def _check_length(length) -> float:
    try:
        value = float(length)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise MeasurementError(f"smoothing length must be a positive finite length in metres, got {length!r}")
    return value


def smooth_max(values, length):
    """Log-sum-exp smooth maximum of ``values`` along the last axis.

    Parameters
    ----------
    values : array_like, shape (..., k), k >= 1
    length : float
        Smoothing length ℓ > 0, in the units of ``values``.

    Returns
    -------
    float or ndarray, shape (...)

    Notes
    -----
    .. math:: \\operatorname{smax}_\\ell(v) = \\ell \\ln \\sum_{i=1}^k e^{v_i/\\ell}
              = m + \\ell \\ln \\sum_i e^{(v_i - m)/\\ell}, \\quad m = \\max_i v_i.

    It is C^∞, its gradient is the softmax weight vector (non-negative, sum 1),
    so it is 1-Lipschitz in the max norm, and its Hessian norm is at most 1/ℓ.
    It is translation-equivariant, ``smax(v + c) = smax(v) + c``, and
    ``max v <= smax(v) <= max v + ℓ ln k``. Values more than ``10 ℓ`` below the
    maximum add less than ``ℓ e^{-10}`` each, so the actual bias is about
    ``ℓ ln(number of near-ties)``. No bias correction is subtracted.
    """
    v = np.asarray(values, dtype=float)
    if v.ndim == 0 or v.shape[-1] == 0:
        raise MeasurementError("smooth_max needs at least one value")
    ell = _check_length(length)
    m = v.max(axis=-1)
    return m + ell * np.log(np.exp((v - m[..., None]) / ell).sum(axis=-1))


def _positions(mesh, x) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.shape != mesh.nodes.shape:
        raise MeasurementError(f"positions must have shape {mesh.nodes.shape}, got {x.shape}")
    if not np.isfinite(x).all():
        raise MeasurementError("positions contain non-finite values")
    return x


def default_smoothing_length(mesh, x) -> float:
    """``SMOOTHING_FRACTION`` × mean edge length of the deformed skin triangles (m)."""
    tri = _positions(mesh, x)[mesh.skin_triangles]
    return SMOOTHING_FRACTION * float(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).mean())


def smoothing_bias(mesh, x, smoothing_length=None) -> float:
    """Worst-case overestimate ``ℓ ln k`` of one smooth extreme (k = number of skin nodes)."""
    ell = default_smoothing_length(mesh, x) if smoothing_length is None else _check_length(smoothing_length)
    return ell * math.log(len(np.unique(mesh.skin_triangles)))


def landmark_positions(mesh, x) -> dict:
    """Deformed landmarks ``N', S', I', M', L'``: name -> (3,) array (m)."""
    x = _positions(mesh, x)
    return {name: x[i].copy() for name, i in mesh.landmarks.items()}


def _tape_radii(mesh, x) -> dict:
    return {r: float(np.linalg.norm(np.diff(x[mesh.meridians[lm]], axis=0), axis=1).sum())
            for r, lm in RADII.items()}


def tape_radii(mesh, x) -> dict:
    """Tape radii ``TR, IR, MR, LR`` (m): deformed lengths of the meridians to S, I, M, L.

    Notes
    -----
    ``XR = Σ_j |x_{c_{j+1}} - x_{c_j}|`` over the meridian chain ``c`` (nipple
    first). On the undeformed cap this is the chord sum of the great-circle
    arc, which is below the arc length ``R φ``, ``φ = atan2(a, R - H)``.
    """
    return _tape_radii(mesh, _positions(mesh, x))


def measure(mesh, x, measurement_set="paper15", smoothing_length=None) -> dict:
    """The five measurements of one posture, in :data:`QUANTITIES` order (SI units).

    Parameters
    ----------
    mesh : breastcore.model.mesh.CapMesh
    x : (N, 3) array_like
        Deformed node positions in metres, torso frame.
    measurement_set : {"paper15", "exact"}
    smoothing_length : float, optional
        ℓ (m) of the smooth extremes. Default: :func:`default_smoothing_length`,
        1 % of the mean deformed skin edge length.

    Returns
    -------
    dict
        quantity -> float: m3, m2, m, m, m.

    Notes
    -----
    With ``MP = y(N')``, tape radii from :func:`tape_radii` and ``z_i, y_i`` over
    the skin nodes (which contain every extreme of the deformed body):

    - paper15 volume ``V = (π/3) MP² (MR + LR + IR - MP)`` (Qiao);
      exact volume ``V = Σ_τ det[x1-x0, x2-x0, x3-x0] / 6``.
    - paper15 area ``A = (π/4)(|N'S'|² + |N'I'|² + |N'M'|² + |N'L'|²)``;
      exact area ``A = Σ_T |(x1-x0) × (x2-x0)| / 2`` over skin triangles.
    - height ``Δh = smax_ℓ(z) + smax_ℓ(-z)`` (bias in ``[0, 2 ℓ ln k]``).
    - frontal depth ``Δf = smax_ℓ(y)`` (bias in ``[0, ℓ ln k]``).
    - back depth ``Δb = MP``.

    With the default ℓ every quantity is invariant under translations in ``x``
    and ``z`` and homogeneous under scaling of ``x`` (degree 1, 2 or 3);
    a translation in ``y`` (off the torso) shifts ``Δf`` and ``Δb`` and changes
    the paper15 volume, which all read ``y`` from the chest wall.
    """
    check_measurement_set(measurement_set)
    x = _positions(mesh, x)
    ell = default_smoothing_length(mesh, x) if smoothing_length is None else _check_length(smoothing_length)
    nipple = x[mesh.landmarks["nipple"]]
    mp = float(nipple[1])
    skin = x[np.unique(mesh.skin_triangles)]
    if measurement_set == "paper15":
        r = _tape_radii(mesh, x)
        volume = math.pi / 3.0 * mp**2 * (r["MR"] + r["LR"] + r["IR"] - mp)
        rim = x[[mesh.landmarks[k] for k in RADII.values()]] - nipple
        area = math.pi / 4.0 * float(np.einsum("ij,ij->", rim, rim))
    else:
        p = x[mesh.tets]
        e = p[:, 1:] - p[:, :1]
        volume = float(np.einsum("ij,ij->", np.cross(e[:, 0], e[:, 1]), e[:, 2])) / 6.0
        t = x[mesh.skin_triangles]
        area = 0.5 * float(np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())
    height = float(smooth_max(skin[:, 2], ell) + smooth_max(-skin[:, 2], ell))
    return {"volume": float(volume), "area": area, "height": height,
            "frontal_depth": float(smooth_max(skin[:, 1], ell)), "back_depth": mp}
