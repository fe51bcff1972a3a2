"""Tests of breastcore.model.geometry: closed-form cap quantities and the smooth mesh map."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from breastcore.model.geometry import CapMap, base_radius, cap_skin_area, cap_volume, check_cap
from breastcore.model.mesh import H0, R0, mesh_cap, mesh_level

GEOMETRIES = [(R0 * k, R0 * k * ratio) for k in (0.5, 1.0, 2.0) for ratio in (0.3, 0.6, 0.97)]


def tet_volumes(nodes, tets):
    p = nodes[tets]
    return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6


@pytest.fixture(scope="module")
def ref():
    mesh = mesh_level("medium")
    return mesh, CapMap(mesh)


def test_closed_forms():
    R, H = 0.0562, 0.05
    a = base_radius(R, H)
    assert a == pytest.approx(math.sqrt(R**2 - (R - H) ** 2), rel=1e-15)
    # volume by integrating the disk slices over y in [0, H]
    slices, _ = quad(lambda y: math.pi * (R**2 - (y - (H - R)) ** 2), 0.0, H)
    assert cap_volume(R, H) == pytest.approx(slices, rel=1e-12)
    assert cap_skin_area(R, H) == pytest.approx(2 * math.pi * R * H, rel=1e-15)
    # hemisphere limit
    assert cap_volume(1.0, 1.0 - 1e-12) == pytest.approx(2 * math.pi / 3, rel=1e-9)


@pytest.mark.parametrize("func", [base_radius, cap_volume, cap_skin_area, check_cap])
@pytest.mark.parametrize("R, H", [(0.05, 0.05), (0.05, 0.06), (0.05, 0.0), (0.05, -0.01),
                                  (-0.05, 0.01), (float("nan"), 0.01), (0.05, float("inf"))])
def test_bad_cap_raises_naming_H_and_R(func, R, H):
    with pytest.raises(ValueError, match=r"H.*R"):
        func(R, H)


def test_identity_at_reference(ref):
    mesh, cmap = ref
    np.testing.assert_allclose(cmap.positions(R0, H0), mesh.nodes, rtol=0, atol=1e-14 * R0)
    at = cmap.mesh_at(R0, H0)
    np.testing.assert_array_equal(at.tets, mesh.tets)


@pytest.mark.parametrize("R, H", GEOMETRIES)
def test_map_to_other_caps(ref, R, H):
    mesh, cmap = ref
    p = cmap.positions(R, H)
    c = np.array([0.0, H - R, 0.0])
    skin = np.unique(mesh.skin_triangles)
    np.testing.assert_allclose(np.linalg.norm(p[skin] - c, axis=1), R, rtol=1e-13)
    assert np.all(p[mesh.back, 1] == 0.0)
    assert np.all(p[~mesh.back, 1] > 0.0)
    rim = mesh.back & np.isin(np.arange(len(p)), skin)
    np.testing.assert_allclose(np.hypot(p[rim, 0], p[rim, 2]), base_radius(R, H), rtol=1e-13)
    for name, zero in (("S", 0), ("I", 0), ("M", 2), ("L", 2)):
        assert np.all(p[mesh.meridians[name], zero] == 0.0)
    a = base_radius(R, H)
    exact = {"nipple": (0, H, 0), "S": (0, 0, a), "I": (0, 0, -a), "M": (-a, 0, 0), "L": (a, 0, 0)}
    for name, pos in exact.items():
        np.testing.assert_allclose(p[mesh.landmarks[name]], pos, rtol=0, atol=1e-14 * R)
    assert np.all(tet_volumes(p, mesh.tets) > 0)


@pytest.mark.parametrize("level", ["coarse", "reference"])
@pytest.mark.parametrize("R, H", GEOMETRIES)
def test_all_tets_stay_positive(level, R, H):
    mesh = mesh_level(level)
    assert np.all(tet_volumes(CapMap(mesh).positions(R, H), mesh.tets) > 0)


@pytest.mark.parametrize("R, H", [(R0, H0), (0.07, 0.03), (0.04, 0.038), (0.1, 0.03)])
def test_derivatives_match_central_differences(ref, R, H):
    _, cmap = ref
    dR, dH = cmap.derivatives(R, H)
    fds = []
    for rel in (1e-4, 1e-6):
        hR, hH = rel * R, rel * H
        fd_R = (cmap.positions(R + hR, H) - cmap.positions(R - hR, H)) / (2 * hR)
        fd_H = (cmap.positions(R, H + hH) - cmap.positions(R, H - hH)) / (2 * hH)
        for fd, an in ((fd_R, dR), (fd_H, dH)):
            assert np.abs(fd - an).max() <= 1e-6 * np.abs(an).max()
        fds.append((fd_R, fd_H))
    for a, b in zip(*fds):
        assert np.abs(a - b).max() <= 1e-6 * np.abs(a).max()


def test_derivatives_keep_constraints(ref):
    mesh, cmap = ref
    dR, dH = cmap.derivatives(0.07, 0.04)
    for d in (dR, dH):
        assert np.all(d[mesh.back, 1] == 0.0)
        assert np.all(d[mesh.meridians["S"], 0] == 0.0) and np.all(d[mesh.meridians["M"], 2] == 0.0)


def test_mesh_at_shares_topology(ref):
    mesh, cmap = ref
    R, H = 0.07, 0.04
    moved = cmap.mesh_at(R, H)
    assert (moved.R, moved.H, moved.fold_angle) == (R, H, mesh.fold_angle)
    for name in ("tets", "skin_triangles", "back_triangles", "fold", "back"):
        np.testing.assert_array_equal(getattr(moved, name), getattr(mesh, name))
    assert moved.landmarks == mesh.landmarks
    for name, chain in mesh.meridians.items():
        np.testing.assert_array_equal(moved.meridians[name], chain)
    np.testing.assert_array_equal(moved.nodes, cmap.positions(R, H))
    assert not moved.nodes.flags.writeable


@pytest.mark.parametrize("R, H", [(0.07, 0.04), (0.05, 0.02), (0.045, 0.043), (0.1, 0.06)])
def test_mapped_volume_matches_cap_and_direct_mesh(R, H):
    mesh = mesh_level("reference")
    moved = CapMap(mesh).mesh_at(R, H)
    vol = tet_volumes(moved.nodes, moved.tets).sum()
    assert abs(vol / cap_volume(R, H) - 1) < 0.01
    direct = mesh_cap(R, H, 0.004)
    assert abs(vol / tet_volumes(direct.nodes, direct.tets).sum() - 1) < 0.01


def test_map_rejects_bad_cap(ref):
    _, cmap = ref
    for func in (cmap.positions, cmap.derivatives, cmap.mesh_at):
        with pytest.raises(ValueError, match=r"H.*R"):
            func(0.05, 0.06)
