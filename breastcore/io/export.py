"""Export solution datasets to mesh files (VTU, XDMF) through meshio."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np


def export_solution(ds, folder, stem, fmt="vtu"):
    """Write ``{stem}_{posture}.{fmt}`` per posture; returns the paths.

    Points are the deformed positions (m); point data ``displacement`` (m) is
    ``position − reference_position`` and ``reference_position`` is kept, so
    ParaView's *Warp By Vector* can also animate from the gravity-free state.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    reference = ds["reference_position"].values
    cells = [("tetra", ds["tetrahedra"].values.astype(np.int64))]
    paths = []
    for name in ds["posture"].values:
        x = ds["position"].sel(posture=name).values
        mesh = meshio.Mesh(x, cells, point_data={"displacement": x - reference,
                                                 "reference_position": reference,
                                                 "fold": ds["fold"].values.astype(np.float64)})
        path = folder / f"{stem}_{name}.{fmt}"
        if fmt == "vtu":
            tmp = path.with_name(path.name + ".tmp")
            meshio.write(tmp, mesh, file_format=fmt)
            tmp.replace(path)
        else:                      # XDMF references a sibling .h5 by name: write in place
            meshio.write(path, mesh, file_format=fmt)
        paths.append(path)
    return paths
