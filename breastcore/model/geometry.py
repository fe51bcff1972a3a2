"""Closed-form geometry of the gravity-free cap and its smooth mesh map.

The cap is ``Ω_g(R, H) = {p : |p - c| <= R, p_y >= 0}`` with ``c = (0, H - R, 0)``
and ``0 < H < R`` (spec section 1). :class:`CapMap` moves the nodes of one
reference mesh onto ``Ω_g(R, H)`` with fixed connectivity, so that measurements
are smooth functions of ``R`` and ``H``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np


def check_cap(R: float, H: float) -> None:
    """Raise ``ValueError`` naming ``H`` and ``R`` unless ``0 < H < R`` (finite)."""
    if not (math.isfinite(R) and math.isfinite(H) and 0.0 < H < R):
        raise ValueError(f"cap needs 0 < H < R, got H={H!r} m, R={R!r} m")


def base_radius(R: float, H: float) -> float:
    """Radius ``a`` of the base disk Γ_B.

    Notes
    -----
    The plane ``y = 0`` cuts the sphere at ``a² = R² - (R - H)² = H (2R - H)``.
    """
    check_cap(R, H)
    return math.sqrt(H * (2.0 * R - H))


def cap_volume(R: float, H: float) -> float:
    """Volume of the cap, ``V = π H² (3R - H) / 3``."""
    check_cap(R, H)
    return math.pi * H**2 * (3.0 * R - H) / 3.0


def cap_skin_area(R: float, H: float) -> float:
    """Area of the spherical skin Γ_F, ``A = 2π R H`` (Archimedes)."""
    check_cap(R, H)
    return 2.0 * math.pi * R * H


def _height(r, R, H):
    """Local cap height ``h(r) = sqrt(R² - r²) - (R - H)`` and ``w = sqrt(R² - r²)``."""
    w = np.sqrt(np.maximum(R * R - r * r, 0.0))
    return w - (R - H), w


class CapMap:
    """Smooth bijection from a fixed-topology reference mesh onto ``Ω_g(R, H)``.

    Parameters
    ----------
    mesh : breastcore.model.mesh.CapMesh
        Reference mesh of ``Ω_g(R0, H0)``; its ``R`` and ``H`` are ``R0, H0``.

    Notes
    -----
    Each node gets canonical coordinates from the reference mesh,
    ``q = (x, z) / a0``, ``s = |q|`` (base-disk radius fraction) and
    ``t = y / h0(a0 s)`` (fraction of the local cap height), where
    ``h(r) = sqrt(R² - r²) - (R - H)``. Skin nodes get ``t = 1`` and back
    nodes ``t = 0`` exactly (the rim, where ``h0 = 0``, is on the back). The map is

    .. math:: p(R, H) = (a q_x,\\; t\\, h(a s),\\; a q_z), \\quad a = \\sqrt{H(2R - H)}.

    So skin nodes land on the new sphere, back nodes stay at ``y = 0`` and nodes
    in the planes ``x = 0`` or ``z = 0`` stay there. With ``w = sqrt(R² - a² s²)``,
    ``∂a/∂R = H/a``, ``∂a/∂H = (R - H)/a``,
    ``∂h/∂R = (R - s² H)/w - 1`` and ``∂h/∂H = 1 - s² (R - H)/w``.
    """

    def __init__(self, mesh):
        self.mesh = mesh
        self.R0, self.H0 = float(mesh.R), float(mesh.H)
        a0 = base_radius(self.R0, self.H0)
        x, y, z = np.asarray(mesh.nodes, dtype=float).T
        self.q = np.column_stack([x / a0, z / a0])
        self.s = np.minimum(np.hypot(self.q[:, 0], self.q[:, 1]), 1.0)
        h0, _ = _height(a0 * self.s, self.R0, self.H0)
        safe = h0 > 1e-12 * self.R0
        t = np.where(safe, y / np.where(safe, h0, 1.0), 0.0)
        skin = np.zeros(len(x), dtype=bool)
        skin[np.asarray(mesh.skin_triangles).ravel()] = True
        t[skin] = 1.0
        t[np.asarray(mesh.back)] = 0.0
        self.t = np.clip(t, 0.0, 1.0)

    def positions(self, R: float, H: float) -> np.ndarray:
        """Node positions ``(N, 3)`` on ``Ω_g(R, H)``; the reference nodes at ``(R0, H0)``."""
        a = base_radius(R, H)
        h, _ = _height(a * self.s, R, H)
        return np.column_stack([a * self.q[:, 0], self.t * h, a * self.q[:, 1]])

    def derivatives(self, R: float, H: float) -> tuple[np.ndarray, np.ndarray]:
        """Analytic ``(∂p/∂R, ∂p/∂H)``, each ``(N, 3)`` (formulas in the class Notes)."""
        a = base_radius(R, H)
        s2 = self.s**2
        _, w = _height(a * self.s, R, H)
        w = np.maximum(w, 1e-300)
        dh_dR = (R - s2 * H) / w - 1.0
        dh_dH = 1.0 - s2 * (R - H) / w
        out = []
        for da, dh in ((H / a, dh_dR), ((R - H) / a, dh_dH)):
            out.append(np.column_stack([da * self.q[:, 0], self.t * dh, da * self.q[:, 1]]))
        return out[0], out[1]

    def mesh_at(self, R: float, H: float):
        """The reference :class:`~breastcore.model.mesh.CapMesh` moved to ``Ω_g(R, H)``.

        Topology, landmarks, meridians, fold and back masks are shared; only
        ``nodes``, ``R`` and ``H`` change.
        """
        nodes = self.positions(R, H)
        return dataclasses.replace(self.mesh, nodes=nodes, R=float(R), H=float(H))
