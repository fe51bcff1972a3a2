"""Stage ``mesh``: a level mesh at the paper's (R, H), or gmsh directly at a true (R, H)."""

from __future__ import annotations

import logging

from breastcore.io.datasets import mesh_dataset, write_netcdf
from breastcore.model.mesh import H0, LEVEL_MESH_SIZE, R0, mesh_cap

log = logging.getLogger(__name__)


def run_mesh(spec, out, config_hash=None):
    """Mesh ``spec["level"]`` at ``spec["R"], spec["H"]`` (default: the paper's) and write it."""
    level = spec["level"]
    R, H = spec.get("R", R0), spec.get("H", H0)
    mesh = mesh_cap(R, H, LEVEL_MESH_SIZE[level], spec.get("fold_angle", 180.0))
    write_netcdf(mesh_dataset(mesh, level, LEVEL_MESH_SIZE[level], config_hash), out)
    log.info("mesh %s: %d nodes, %d tets", level, len(mesh.nodes), len(mesh.tets))
