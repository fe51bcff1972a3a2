"""Tetrahedral meshes of the gravity-free cap ``Ω_g(R, H)`` made with gmsh.

:func:`mesh_cap` is the direct gmsh path (one mesh per ``(R, H)``, used for
synthetic truth); :func:`mesh_level` meshes the spec's named levels (section 1).
To move a mesh smoothly with ``(R, H)`` use :class:`breastcore.model.geometry.CapMap`.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from breastcore.model.geometry import base_radius, check_cap
from breastcore.model.parameters import PARAMETER_INFO

#: The paper's geometry Λ̄ (metres), at which the level sizes are calibrated.
R0 = PARAMETER_INFO["R"].default
H0 = PARAMETER_INFO["H"].default

#: Target node counts: the spec's levels (paper) plus two benchmark levels.
LEVEL_NODE_COUNTS = {"coarse": 226, "medium": 572, "medium-thin": 1014, "thin": 1404, "very-thin": 2127,
                     "ultra-thin": 2498, "reference": 2948, "fine10k": 10_000, "fine50k": 50_000}

#: gmsh characteristic length (metres) per level: a bisection on log(size), then a
#: ±2 % scan for the closest node count, run once offline with gmsh 4.15 at (R0, H0).
LEVEL_MESH_SIZE = {
    "coarse": 0.01638,  # 237 nodes, 817 tets
    "medium": 0.01016,  # 573 nodes, 2120 tets
    "medium-thin": 0.007841,  # 1029 nodes, 4156 tets
    "thin": 0.006792,  # 1427 nodes, 6052 tets
    "very-thin": 0.005591,  # 2117 nodes, 9391 tets
    "ultra-thin": 0.005358,  # 2515 nodes, 11372 tets
    "reference": 0.005023,  # 3010 nodes, 13834 tets
    "fine10k": 0.003132,  # 10013 nodes, 50864 tets
    "fine50k": 0.001745,  # 49609 nodes, 275129 tets
}

_TOL = 1e-9  # relative to R: "on a plane", "is a landmark"
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])  # outward, positive tet


@dataclasses.dataclass(frozen=True, eq=False)
class CapMesh:
    """P1 tet mesh of ``Ω_g(R, H)``; arrays become read-only (copied unless already so)."""

    nodes: np.ndarray  # (N, 3) float64, metres
    tets: np.ndarray  # (T, 4) int64, positive: det[P1-P0, P2-P0, P3-P0] > 0
    skin_triangles: np.ndarray  # (S, 3) int64, normal (P1-P0) x (P2-P0) outward
    back_triangles: np.ndarray  # (B, 3) int64, normal to -y (outward)
    fold: np.ndarray  # (N,) bool, on the fold γ_D
    back: np.ndarray  # (N,) bool, on Γ_B (y == 0, rim included)
    landmarks: dict  # "nipple", "S", "I", "M", "L" -> node index
    meridians: dict  # "S", "I", "M", "L" -> skin node chain, nipple first, landmark last
    R: float  # sphere radius, metres
    H: float  # cap height, metres
    fold_angle: float  # fold arc θ_D, degrees

    def __post_init__(self):
        def frozen(value, dtype):  # read-only arrays that own their data are shared, not copied
            if isinstance(value, np.ndarray) and value.dtype == dtype and not value.flags.writeable \
                    and value.base is None:
                return value
            arr = np.array(value, dtype=dtype)
            arr.setflags(write=False)
            return arr
        for name in ("nodes", "tets", "skin_triangles", "back_triangles", "fold", "back"):
            dtype = np.float64 if name == "nodes" else bool if name in ("fold", "back") else np.int64
            object.__setattr__(self, name, frozen(getattr(self, name), dtype))
        object.__setattr__(self, "landmarks", {k: int(v) for k, v in self.landmarks.items()})
        object.__setattr__(self, "meridians", {k: frozen(v, np.int64) for k, v in self.meridians.items()})
        for name in ("R", "H", "fold_angle"):
            object.__setattr__(self, name, float(getattr(self, name)))


def _check_fold_angle(fold_angle: float) -> float:
    fold_angle = float(fold_angle)
    if not (math.isfinite(fold_angle) and 0.0 < fold_angle <= 360.0):
        raise ValueError(f"fold_angle must be in (0, 360] degrees, got {fold_angle!r}")
    return fold_angle


def rim_mask(mesh: CapMesh) -> np.ndarray:
    """Nodes on the base rim: back nodes at radius ``>= a (1 - 1e-9)`` or shared with the skin."""
    radius = np.hypot(mesh.nodes[:, 0], mesh.nodes[:, 2])
    on_skin = np.zeros(len(mesh.nodes), dtype=bool)
    on_skin[mesh.skin_triangles.ravel()] = True
    return mesh.back & (on_skin | (radius >= base_radius(mesh.R, mesh.H) * (1.0 - 1e-9)))


def fold_mask(nodes: np.ndarray, rim: np.ndarray, fold_angle: float) -> np.ndarray:
    """Rim nodes whose polar angle ``atan2(x, -z)`` is within ``±fold_angle/2`` (degrees) of ``-z``."""
    polar = np.arctan2(nodes[:, 0], -nodes[:, 2])
    return rim & (np.abs(polar) <= math.radians(fold_angle) / 2.0 + 1e-9)


def refold(mesh: CapMesh, fold_angle: float) -> CapMesh:
    """The same mesh with the fold γ_D recomputed for another ``fold_angle`` (degrees)."""
    fold_angle = _check_fold_angle(fold_angle)
    fold = fold_mask(mesh.nodes, rim_mask(mesh), fold_angle)
    return dataclasses.replace(mesh, fold=fold, fold_angle=fold_angle)


def _gmsh_tets(R: float, H: float, size: float) -> tuple[np.ndarray, np.ndarray]:
    """Run gmsh: 4 conformal quarter caps (split by x=0, z=0); return nodes and tets."""
    import gmsh  # imported here: importing breastcore.model.mesh should not load gmsh
    options = {"General.Terminal": 0, "General.NumThreads": 1, "Mesh.MeshSizeMin": size,
               "Mesh.MeshSizeMax": size, "Mesh.MeshSizeFromPoints": 0, "Mesh.MeshSizeFromCurvature": 0,
               "Mesh.Algorithm": 6, "Mesh.Algorithm3D": 1, "Mesh.RandomSeed": 1}
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        for name, value in options.items():
            gmsh.option.setNumber(name, value)
        occ = gmsh.model.occ
        quarters = []
        for x0 in (-R, 0.0):
            for z0 in (-R, 0.0):
                box = occ.addBox(x0, 0.0, z0, R, 2.0 * R, R)
                ball = occ.addSphere(0.0, H - R, 0.0, R)
                quarters += occ.intersect([(3, ball)], [(3, box)])[0]
        occ.fragment(quarters[:1], quarters[1:])
        occ.synchronize()
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, tet_tags = gmsh.model.mesh.getElementsByType(4)
    finally:
        gmsh.finalize()
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    return coords.reshape(-1, 3), index[tet_tags.astype(np.int64)].reshape(-1, 4)


def orient(nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Copy of ``tets`` with two vertices swapped where ``det[P1-P0, P2-P0, P3-P0] < 0``."""
    p = nodes[tets]
    flip = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) < 0
    tets = tets.copy()
    tets[flip, 1:3] = tets[flip, 2:0:-1]
    return tets


def boundary_faces(tets: np.ndarray, n_nodes: int) -> np.ndarray:
    """Faces used by exactly one tet, oriented outward (tets must be positive)."""
    faces = tets[:, _TET_FACES].reshape(-1, 3)
    s = np.sort(faces, axis=1)
    key = (s[:, 0] * n_nodes + s[:, 1]) * n_nodes + s[:, 2]
    _, first, count = np.unique(key, return_index=True, return_counts=True)
    return faces[first[count == 1]]


def _snap(nodes, back, skin, R, H):
    """Put boundary nodes exactly on their surfaces (gmsh is off by ~1e-16 R)."""
    a = base_radius(R, H)
    nodes = nodes.copy()
    nodes[np.abs(nodes) < _TOL * R] = 0.0  # the planes x = 0, y = 0 and z = 0
    rim, top = back & skin, skin & ~back
    nodes[np.ix_(rim, [0, 2])] *= (a / np.hypot(nodes[rim, 0], nodes[rim, 2]))[:, None]
    r = np.hypot(nodes[top, 0], nodes[top, 2])
    nodes[top, 1] = np.sqrt(R * R - r * r) - (R - H)
    exact = {"nipple": (0, H, 0), "S": (0, 0, a), "I": (0, 0, -a), "M": (-a, 0, 0), "L": (a, 0, 0)}
    landmarks = {}
    for name, pos in exact.items():
        dist = np.linalg.norm(nodes - np.array(pos, dtype=float), axis=1)
        landmarks[name] = int(np.argmin(dist))
        if dist[landmarks[name]] >= 1e-9 * R:
            raise RuntimeError(f"landmark {name} is not a mesh node")
        nodes[landmarks[name]] = pos
    return nodes, landmarks


def _meridians(nodes, skin, landmarks, R, H):
    """Skin node chains in the planes x = 0 (S, I) and z = 0 (M, L), sorted from the nipple."""
    x, y, z = nodes.T
    angle = np.arctan2(np.hypot(x, z), y - (H - R))  # geodesic angle from the nipple
    chains = {"S": (x == 0) & (z >= 0), "I": (x == 0) & (z <= 0),
              "M": (z == 0) & (x <= 0), "L": (z == 0) & (x >= 0)}
    meridians = {}
    for name, sel in chains.items():
        idx = np.flatnonzero(sel & skin)
        meridians[name] = idx[np.argsort(angle[idx], kind="stable")]
        if meridians[name][0] != landmarks["nipple"] or meridians[name][-1] != landmarks[name]:
            raise RuntimeError(f"meridian {name} does not join the nipple to {name}")
    return meridians


@functools.lru_cache(maxsize=32)
def _build(R: float, H: float, size: float, fold_angle: float) -> CapMesh:
    raw_nodes, raw_tets = _gmsh_tets(R, H, size)
    used, tets = np.unique(raw_tets, return_inverse=True)  # keep only nodes of tets
    nodes, tets = raw_nodes[used], orient(raw_nodes[used], tets.reshape(-1, 4))
    faces = boundary_faces(tets, len(nodes))
    on_back = np.all(np.abs(nodes[faces, 1]) < _TOL * R, axis=1)
    back, skin = np.zeros((2, len(nodes)), dtype=bool)
    back[faces[on_back].ravel()] = True
    skin[faces[~on_back].ravel()] = True
    nodes, landmarks = _snap(nodes, back, skin, R, H)
    meridians = _meridians(nodes, skin, landmarks, R, H)
    fold = fold_mask(nodes, back & skin, fold_angle)
    return CapMesh(nodes, tets, faces[~on_back], faces[on_back], fold, back, landmarks, meridians,
                   R, H, fold_angle)


def mesh_cap(R: float, H: float, size: float, fold_angle: float = 180.0) -> CapMesh:
    """Mesh ``Ω_g(R, H)`` directly with gmsh (OCC kernel, uniform size).

    Parameters
    ----------
    R, H : float
        Sphere radius and cap height (metres), ``0 < H < R``.
    size : float or str
        Uniform gmsh characteristic length (metres), > 0, or a level name.
    fold_angle : float
        Fold arc θ_D (degrees), in ``(0, 360]``.

    Returns
    -------
    CapMesh
        Cached: identical arguments return the same read-only object.

    Notes
    -----
    Four quarter caps (the ball cut by ``y >= 0`` and the signs of x and z) are
    fragmented to be conformal, so meridians are mesh edges and landmarks are
    vertices. gmsh runs single-threaded (Frontal-Delaunay 2D, Delaunay 3D), so
    it is deterministic. Boundary nodes are then snapped exactly onto their
    surfaces (planes, rim radius ``a``, skin sphere above their ``(x, z)``).
    """
    check_cap(float(R), float(H))
    return _build(float(R), float(H), resolve_size(size), _check_fold_angle(fold_angle))


def resolve_size(level_or_size) -> float:
    """Mesh size in metres of a named level, or a positive size passed through."""
    if isinstance(level_or_size, str):
        if level_or_size not in LEVEL_MESH_SIZE:
            raise ValueError(f"unknown mesh level {level_or_size!r}; valid levels: {', '.join(LEVEL_MESH_SIZE)}")
        return LEVEL_MESH_SIZE[level_or_size]
    size = float(level_or_size)
    if not (math.isfinite(size) and size > 0):
        raise ValueError(f"size must be a positive length in metres or a level name, got {level_or_size!r}")
    return size


def mesh_level(level, R: float = R0, H: float = H0, fold_angle: float = 180.0) -> CapMesh:
    """Mesh of a named level (or an explicit size in metres) for ``Ω_g(R, H)``; cached."""
    return mesh_cap(R, H, level, fold_angle)
