"""Export solution datasets to mesh files (VTU, XDMF) through meshio."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np


def cell_kinematics(reference, position, tets):
    """``(det F, largest principal stretch)`` per tetrahedron, both dimensionless, ``(T,)`` each.

    ``F = D_s D_m⁻¹`` with ``D_m``, ``D_s`` the edge matrices of the tet in the reference
    and the deformed positions; the principal stretches are the square roots of the
    eigenvalues of ``Fᵀ F``.
    """
    def edges(x):
        return np.stack([x[tets[:, k]] - x[tets[:, 0]] for k in (1, 2, 3)], axis=-1)   # (T, 3, 3), columns
    F = edges(position) @ np.linalg.inv(edges(reference))
    return np.linalg.det(F), np.sqrt(np.linalg.eigvalsh(np.swapaxes(F, 1, 2) @ F)[:, -1])


def export_solution(ds, folder, stem, fmt="vtu"):
    """Write ``{stem}_{posture}.{fmt}`` per posture; returns the paths.

    Points are the deformed positions (m). Field names carry their units:

    - point data ``displacement_m`` = ``position − reference_position`` and
      ``reference_position_m`` (so that ParaView's *Warp By Vector* can also animate from
      the gravity-free state), ``fold`` (1 on the fixed fold nodes, else 0);
    - cell data ``det_F`` and ``max_stretch`` (dimensionless, :func:`cell_kinematics`):
      where the tissue is compressed, and where it is stretched most.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    reference = ds["reference_position"].values
    cells = [("tetra", ds["tetrahedra"].values.astype(np.int64))]
    paths = []
    for name in ds["posture"].values:
        x = ds["position"].sel(posture=name).values
        det_F, stretch = cell_kinematics(reference, x, cells[0][1])
        mesh = meshio.Mesh(x, cells, point_data={"displacement_m": x - reference,
                                                 "reference_position_m": reference,
                                                 "fold": ds["fold"].values.astype(np.float64)},
                           cell_data={"det_F": [det_F], "max_stretch": [stretch]})
        path = folder / f"{stem}_{name}.{fmt}"
        if fmt == "vtu":
            tmp = path.with_name(path.name + ".tmp")
            meshio.write(tmp, mesh, file_format=fmt)
            tmp.replace(path)
        else:                      # XDMF references a sibling .h5 by name: write in place
            meshio.write(path, mesh, file_format=fmt)
        paths.append(path)
    return paths
