"""Tests of breastcore.model.mesh: gmsh caps, levels, boundary, landmarks, meridians, fold."""

import math

import numpy as np
import pytest

from breastcore.model.geometry import base_radius, cap_skin_area, cap_volume
from breastcore.model.mesh import (
    H0,
    LEVEL_MESH_SIZE,
    LEVEL_NODE_COUNTS,
    R0,
    _build,
    mesh_cap,
    mesh_level,
    refold,
    resolve_size,
)

SPEC_LEVELS = ["coarse", "medium", "medium-thin", "thin", "very-thin", "ultra-thin", "reference"]


def tet_volumes(nodes, tets):
    p = nodes[tets]
    return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6


def tri_normals(nodes, tris):
    p = nodes[tris]
    return 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def rim_nodes(m):
    a = base_radius(m.R, m.H)
    return m.back & np.isclose(np.hypot(m.nodes[:, 0], m.nodes[:, 2]), a, rtol=1e-12)


@pytest.fixture(scope="module")
def medium():
    return mesh_level("medium")


@pytest.mark.parametrize("level", SPEC_LEVELS)
def test_level_node_counts_within_15_percent(level):
    n = len(mesh_level(level).nodes)
    assert abs(n / LEVEL_NODE_COUNTS[level] - 1) <= 0.15, (level, n)


def test_level_tables_and_resolve_size():
    assert set(SPEC_LEVELS) | {"fine10k", "fine50k"} == set(LEVEL_MESH_SIZE) == set(LEVEL_NODE_COUNTS)
    sizes = [LEVEL_MESH_SIZE[lv] for lv in SPEC_LEVELS]
    assert all(s1 > s2 > 0 for s1, s2 in zip(sizes, sizes[1:]))
    assert resolve_size("coarse") == LEVEL_MESH_SIZE["coarse"]
    assert resolve_size(0.01) == 0.01
    with pytest.raises(ValueError, match="valid levels: coarse"):
        resolve_size("nope")
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="size"):
            resolve_size(bad)


def test_landmarks_are_nodes_at_exact_positions(medium):
    a = base_radius(R0, H0)
    exact = {"nipple": (0, H0, 0), "S": (0, 0, a), "I": (0, 0, -a), "M": (-a, 0, 0), "L": (a, 0, 0)}
    assert set(medium.landmarks) == set(exact)
    for name, pos in exact.items():
        assert isinstance(medium.landmarks[name], int)
        np.testing.assert_array_equal(medium.nodes[medium.landmarks[name]], pos)


def test_meridians(medium):
    c = np.array([0.0, H0 - R0, 0.0])
    plane = {"S": (0, 1), "I": (0, -1), "M": (2, -1), "L": (2, 1)}  # zero coordinate, sign of other
    assert set(medium.meridians) == set(plane)
    for name, chain in medium.meridians.items():
        assert chain.dtype == np.int64 and len(chain) >= 4
        assert chain[0] == medium.landmarks["nipple"] and chain[-1] == medium.landmarks[name]
        p = medium.nodes[chain]
        np.testing.assert_allclose(np.linalg.norm(p - c, axis=1), R0, rtol=1e-14)
        zero, sign = plane[name]
        assert np.all(p[:, zero] == 0.0)
        assert np.all(sign * p[:, 2 - zero] >= 0)
        assert np.all(np.diff(p[:, 1]) < 0)  # monotone away from the nipple
        assert len(np.unique(chain)) == len(chain)
    # the chains are connected by mesh edges
    edges = {tuple(sorted(e)) for t in medium.tets for e in ((t[0], t[1]), (t[0], t[2]), (t[0], t[3]),
                                                              (t[1], t[2]), (t[1], t[3]), (t[2], t[3]))}
    for chain in medium.meridians.values():
        assert all(tuple(sorted(e)) in edges for e in zip(chain[:-1], chain[1:]))


def test_tets_positive_and_boundary_is_skin_plus_back(medium):
    m = medium
    assert m.nodes.dtype == np.float64 and m.tets.dtype == np.int64
    assert np.all(tet_volumes(m.nodes, m.tets) > 0)
    assert np.array_equal(np.unique(m.tets), np.arange(len(m.nodes)))  # every node is used
    counts = {}
    for t in m.tets:
        for f in (t[[0, 1, 2]], t[[0, 1, 3]], t[[0, 2, 3]], t[[1, 2, 3]]):
            key = tuple(sorted(f))
            counts[key] = counts.get(key, 0) + 1
    boundary = {k for k, v in counts.items() if v == 1}
    skin = {tuple(sorted(f)) for f in m.skin_triangles}
    back = {tuple(sorted(f)) for f in m.back_triangles}
    assert not skin & back and skin | back == boundary
    assert len(skin) == len(m.skin_triangles) and len(back) == len(m.back_triangles)
    # outward orientation
    c = np.array([0.0, H0 - R0, 0.0])
    n_skin = tri_normals(m.nodes, m.skin_triangles)
    assert np.all(np.einsum("ij,ij->i", n_skin, m.nodes[m.skin_triangles].mean(axis=1) - c) > 0)
    n_back = tri_normals(m.nodes, m.back_triangles)
    assert np.all(n_back[:, 1] < 0) and np.allclose(n_back[:, [0, 2]], 0.0, atol=1e-20)
    # back mask: exactly the nodes of back triangles, all at y == 0
    assert np.array_equal(np.flatnonzero(m.back), np.unique(m.back_triangles))
    assert np.all(m.nodes[m.back, 1] == 0.0) and np.all(m.nodes[~m.back, 1] > 0.0)
    skin_nodes = np.unique(m.skin_triangles)
    r = np.linalg.norm(m.nodes[skin_nodes] - c, axis=1)
    np.testing.assert_allclose(r, R0, rtol=1e-14)


def test_volume_and_areas_converge():
    errors = []
    for level in ("coarse", "medium", "thin", "reference"):
        m = mesh_level(level)
        vol = tet_volumes(m.nodes, m.tets).sum()
        skin = np.linalg.norm(tri_normals(m.nodes, m.skin_triangles), axis=1).sum()
        back = np.linalg.norm(tri_normals(m.nodes, m.back_triangles), axis=1).sum()
        errors.append((abs(vol / cap_volume(R0, H0) - 1), abs(skin / cap_skin_area(R0, H0) - 1),
                       abs(back / (math.pi * base_radius(R0, H0) ** 2) - 1)))
    errors = np.array(errors)
    assert np.all(np.diff(errors, axis=0) < 0), errors  # every error decreases with refinement
    assert np.all(errors[-1] < 0.03), errors[-1]


def test_fold_default_is_lower_half_of_rim(medium):
    m = medium
    rim = rim_nodes(m)
    assert m.fold_angle == 180.0
    np.testing.assert_array_equal(m.fold, rim & (m.nodes[:, 2] <= 0))
    for name in ("M", "L", "I"):
        assert m.fold[m.landmarks[name]]
    assert not m.fold[m.landmarks["S"]]


def test_fold_90_degrees_and_refold(medium):
    m90 = mesh_level("medium", fold_angle=90.0)
    assert m90.fold_angle == 90.0
    assert 0 < m90.fold.sum() < medium.fold.sum()
    p = m90.nodes[m90.fold]
    assert np.all(np.abs(np.arctan2(p[:, 0], -p[:, 2])) <= math.pi / 4 + 1e-9)
    assert m90.fold[m90.landmarks["I"]] and not m90.fold[m90.landmarks["M"]]
    again = refold(medium, 90.0)
    np.testing.assert_array_equal(again.fold, m90.fold)
    assert again.tets is medium.tets or np.array_equal(again.tets, medium.tets)
    np.testing.assert_array_equal(refold(medium, 360.0).fold, rim_nodes(medium))
    np.testing.assert_array_equal(refold(m90, 180.0).fold, medium.fold)


def test_cached_readonly_and_deterministic():
    m = mesh_level("coarse")
    assert mesh_level("coarse") is m
    assert mesh_cap(R0, H0, LEVEL_MESH_SIZE["coarse"]) is m
    for arr in (m.nodes, m.tets, m.skin_triangles, m.back_triangles, m.fold, m.back, *m.meridians.values()):
        assert not arr.flags.writeable
    with pytest.raises(ValueError):
        m.nodes[0, 0] = 1.0
    fresh = _build.__wrapped__(R0, H0, LEVEL_MESH_SIZE["coarse"], 180.0)  # runs gmsh again
    assert fresh is not m
    for name in ("nodes", "tets", "skin_triangles", "back_triangles", "fold", "back"):
        np.testing.assert_array_equal(getattr(fresh, name), getattr(m, name))
    assert fresh.landmarks == m.landmarks


def test_mesh_cap_other_geometry():
    R, H = 0.08, 0.03
    m = mesh_cap(R, H, 0.008, fold_angle=120.0)
    assert (m.R, m.H, m.fold_angle) == (R, H, 120.0)
    assert np.all(tet_volumes(m.nodes, m.tets) > 0)
    np.testing.assert_array_equal(m.nodes[m.landmarks["S"]], (0, 0, base_radius(R, H)))
    assert abs(tet_volumes(m.nodes, m.tets).sum() / cap_volume(R, H) - 1) < 0.03


@pytest.mark.parametrize("kwargs, name", [
    (dict(R=0.05, H=0.06, size=0.01), "H"),
    (dict(R=0.05, H=0.0, size=0.01), "H"),
    (dict(R=-0.05, H=0.01, size=0.01), "R"),
    (dict(R=R0, H=H0, size=0.0), "size"),
    (dict(R=R0, H=H0, size=-0.01), "size"),
    (dict(R=R0, H=H0, size=0.01, fold_angle=0.0), "fold_angle"),
    (dict(R=R0, H=H0, size=0.01, fold_angle=400.0), "fold_angle"),
])
def test_bad_inputs(kwargs, name):
    with pytest.raises(ValueError, match=name):
        mesh_cap(**kwargs)


def test_bad_level_and_refold_inputs(medium):
    with pytest.raises(ValueError, match="valid levels"):
        mesh_level("ultra")
    with pytest.raises(ValueError, match="fold_angle"):
        refold(medium, -10.0)
