"""netCDF datasets: atomic writes, provenance, and the mesh and solution schemas.

Every variable carries CF-style ``units`` and ``long_name``; every dataset carries
``breastcore_version``, ``source_hash``, ``stage``, ``parameters`` (JSON) and
``config_hash`` attributes. The schemas are documented in ``docs/datasets.md``.
"""

from __future__ import annotations

import datetime
import json
import os
import secrets
from pathlib import Path

import numpy as np
import xarray as xr

from breastcore import __version__, source_hash
from breastcore.inverse.measurements import QUANTITIES, UNITS
from breastcore.model.mesh import CapMesh
from breastcore.model.parameters import IDENTIFIED, PARAMETER_INFO, Parameters

LANDMARKS = ("nipple", "S", "I", "M", "L")
MERIDIANS = ("S", "I", "M", "L")


def write_netcdf(ds: xr.Dataset, path) -> Path:
    """Write ``ds`` to ``path`` atomically: a temporary file in the same folder, then a rename.

    Readers never see a half-written file. Missing parent folders are created. The file's
    mode follows the umask, as for any file the workflow writes (0644 under umask 022).
    """
    missing = [name for name, var in ds.variables.items() if "units" not in var.attrs or "long_name" not in var.attrs]
    if missing:
        raise ValueError(f"variables without units/long_name: {missing}")
    return _write_atomically(path, lambda tmp: ds.to_netcdf(tmp, engine="netcdf4"))


def write_text(text: str, path) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically, as :func:`write_netcdf` writes a dataset."""
    return _write_atomically(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def _write_atomically(path, write) -> Path:
    """``write(tmp)`` to a new temporary file beside ``path`` (its folder created), then rename it to ``path``.

    No temporary file is left behind, whether ``write`` succeeds or raises.
    """
    path = Path(path)
    if path.exists() and not path.is_file():            # the rename would replace a device or fail on a folder
        raise IsADirectoryError(f"cannot write {str(path)!r}: it is a folder") if path.is_dir() else \
            FileExistsError(f"cannot write {str(path)!r}: it exists and is not a regular file (a device or a pipe)")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _new_temporary(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def _new_temporary(path: Path) -> str:
    """Create an empty, unused ``<name>.<random>.tmp`` beside ``path``, with mode 0666 less the umask.

    Not ``tempfile.mkstemp``: its file is mode 0600 whatever the umask, and netCDF, which
    truncates the file it is given, keeps that mode, so the renamed dataset was 0600.
    Opening with ``O_EXCL`` and mode 0666 lets the kernel apply the umask.
    """
    while True:
        tmp = str(path.with_name(f"{path.name}.{secrets.token_hex(4)}.tmp"))
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            return tmp
        except FileExistsError:
            continue


def provenance(stage: str, parameters=None, config_hash: str | None = None, **extra) -> dict:
    """Global attributes: stage, version, source hash, parameters (JSON), config hash, time."""
    attrs = {
        "Conventions": "CF-1.10",
        "stage": stage,
        "breastcore_version": __version__,
        "source_hash": source_hash(),
        "config_hash": config_hash or "none",
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "parameters": json.dumps(parameters.as_dict() if isinstance(parameters, Parameters) else (parameters or {})),
    }
    attrs.update({k: (json.dumps(v) if isinstance(v, (dict, list, tuple)) else v) for k, v in extra.items()})
    return attrs


def _var(dims, data, units, long_name, **attrs):
    return xr.Variable(dims, data, {"units": units, "long_name": long_name, **attrs})


def per_entry_units(units) -> str:
    """The ``units`` attribute of a variable whose entries along one dimension differ in unit (the
    six parameters, the five measurements): each entry's unit in order, comma-separated, ``m, m, Pa``.

    Not a UDUNITS string, on purpose: a CF unit parser (cf-units, pint) refuses it, where the
    space-separated form used before (``m m Pa Pa Pa Pa``) parsed silently as m²·Pa⁴. The
    coordinate ``parameter_units`` or ``quantity_units`` holds the same units one per entry.
    """
    return ", ".join(units)


#: The ``units`` attribute of a variable along ``parameter`` (Λ) or ``quantity`` (M), per entry.
PARAMETER_UNIT_LIST = per_entry_units(PARAMETER_INFO[p].units for p in IDENTIFIED)
QUANTITY_UNIT_LIST = per_entry_units(UNITS[q] for q in QUANTITIES)


def mesh_variables(mesh: CapMesh) -> dict:
    """The mesh part shared by the mesh and solution datasets."""
    chain_len = max(len(mesh.meridians[m]) for m in MERIDIANS)
    chains = np.full((len(MERIDIANS), chain_len), -1, dtype=np.int64)
    for i, m in enumerate(MERIDIANS):
        chains[i, : len(mesh.meridians[m])] = mesh.meridians[m]
    return {
        "reference_position": _var(("node", "xyz"), mesh.nodes, "m", "gravity-free node position (torso frame)"),
        "tetrahedra": _var(("tet", "tet_corner"), mesh.tets.astype(np.int64), "1", "tetrahedron node indices (0-based)"),
        "skin_triangles": _var(("skin_face", "tri_corner"), mesh.skin_triangles.astype(np.int64), "1",
                               "skin triangle node indices, outward normal (Γ_F)"),
        "back_triangles": _var(("back_face", "tri_corner"), mesh.back_triangles.astype(np.int64), "1",
                               "back triangle node indices (Γ_B, torso plane)"),
        "fold": _var(("node",), mesh.fold.astype(np.int8), "1", "1 where the node is fixed on the infra-mammary fold γ_D"),
        "back": _var(("node",), mesh.back.astype(np.int8), "1", "1 where the node lies on the back plane Γ_B"),
        "landmark_node": _var(("landmark",), np.array([mesh.landmarks[k] for k in LANDMARKS], np.int64), "1",
                              "node index of each landmark"),
        "meridian_node": _var(("meridian", "meridian_point"), chains, "1",
                              "skin node chain from the nipple to each rim landmark (-1 pads)"),
    }


def mesh_coords() -> dict:
    return {
        "xyz": _var(("xyz",), np.array(["x", "y", "z"]), "1", "torso axis: x lateral, y anterior, z superior"),
        "landmark": _var(("landmark",), np.array(LANDMARKS), "1", "landmark name"),
        "meridian": _var(("meridian",), np.array(MERIDIANS), "1", "rim landmark ending the meridian"),
    }


def mesh_dataset(mesh: CapMesh, level: str, size: float, config_hash=None) -> xr.Dataset:
    ds = xr.Dataset(mesh_variables(mesh), coords=mesh_coords())
    ds.attrs = provenance("mesh", {"R": mesh.R, "H": mesh.H, "fold_angle": mesh.fold_angle},
                          config_hash, mesh_level=level, mesh_size=float(size),
                          title=f"breastcore gravity-free cap mesh ({level})")
    return ds


def mesh_from_dataset(ds: xr.Dataset) -> CapMesh:
    """Rebuild the :class:`CapMesh` stored in a mesh or solution dataset."""
    params = json.loads(ds.attrs["parameters"])
    landmarks = dict(zip(LANDMARKS, (int(i) for i in ds["landmark_node"].values)))
    chains = ds["meridian_node"].values
    meridians = {m: chains[i][chains[i] >= 0] for i, m in enumerate(MERIDIANS)}
    return CapMesh(nodes=ds["reference_position"].values, tets=ds["tetrahedra"].values,
                   skin_triangles=ds["skin_triangles"].values, back_triangles=ds["back_triangles"].values,
                   fold=ds["fold"].values.astype(bool), back=ds["back"].values.astype(bool),
                   landmarks=landmarks, meridians=meridians, R=float(params["R"]), H=float(params["H"]),
                   fold_angle=float(params["fold_angle"]))


def parameter_variables(params: Parameters) -> dict:
    """One scalar variable per model parameter, with units and long name."""
    out = {}
    for name, value in params.as_dict().items():
        info = PARAMETER_INFO[name]
        out[name] = _var((), float(value), info.units, info.long_name, source=info.source)
    return out


def open_dataset(path) -> xr.Dataset:
    """Load a dataset fully into memory and close the file (so it can be replaced)."""
    with xr.open_dataset(path) as ds:
        return ds.load()
