"""Shared fixtures: a tiny structured tet mesh for derivative checks."""

import numpy as np
import pytest

# Kuhn subdivision of the unit cube into 6 positively oriented tetrahedra.
_KUHN = np.array([[0, 1, 3, 7], [0, 1, 7, 5], [0, 2, 7, 3], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 7, 6]])


def box_mesh(n=2, size=0.05):
    """Structured tet mesh of a cube of side ``size`` (m) with ``n`` cells a side.

    Returns nodes (N,3), tets (T,4), top triangles (z = size) and bottom
    triangles (y = 0), all as arrays.
    """
    g = np.linspace(0.0, size, n + 1)
    X, Y, Z = np.meshgrid(g, g, g, indexing="ij")
    nodes = np.column_stack([X.ravel(), Y.ravel(), Z.ravel()])
    idx = np.arange(nodes.shape[0]).reshape(n + 1, n + 1, n + 1)
    tets = []
    for i in range(n):
        for j in range(n):
            for k in range(n):
                corner = [idx[i + a, j + b, k + c] for c in (0, 1) for b in (0, 1) for a in (0, 1)]
                tets.extend([[corner[v] for v in t] for t in _KUHN])
    tets = np.array(tets)
    e = nodes[tets[:, 1:]] - nodes[tets[:, :1]]
    flip = np.linalg.det(e) < 0
    tets[flip] = tets[flip][:, [0, 2, 1, 3]]

    def face(axis, value):
        tris = []
        on = np.isclose(nodes[:, axis], value)
        for t in tets:
            sel = [v for v in t if on[v]]
            if len(sel) == 3:
                tris.append(sel)
        return np.array(tris)

    return nodes, tets, face(2, size), face(1, 0.0)


@pytest.fixture
def small_box():
    return box_mesh(2)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
