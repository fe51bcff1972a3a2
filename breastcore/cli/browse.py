"""``breastcore show FILE.nc`` and ``breastcore list FOLDER``: browse result datasets."""

from __future__ import annotations

import json
from pathlib import Path

from breastcore.cli.options import UsageError, dataset_file

_KEY_NUMBERS = {
    "mesh": ["reference_position", "tetrahedra"],
    "solve": ["newton_iterations", "gradient_norm", "tolerance", "converged", "min_det_F", "torso_penetration",
              "wall_time"],
    "measure": ["measurement"],
    "identify": ["estimate", "interval_low", "interval_high", "determined", "relative_error", "cost",
                 "singular_values"],
    "sensitivity": ["linearised", "finite"],
    "stability": ["outcome", "iterations", "min_det_F"],
    "extreme": ["guess_label", "guess_outcome", "guess_max_error"],
    "scene": ["mean_abs_error", "verdict", "wall_time", "nipple_displacement", "torso_penetration", "estimate",
              "interval_low", "interval_high", "determined"],
}
#: Key numbers of scene summaries whose kind has its own (the others use the "scene" list).
_SCENE_KEY_NUMBERS = {
    "patient": ["newton_iterations", "min_det_F", "max_stretch", "torso_penetration"],    # after the clinical block
    "calibration": ["table2_residual", "paper_table2_residual", "passed", "measurement_difference",
                    "sliding_difference", "identification_error"],
}


def register(sub):
    p = sub.add_parser("show", help="print a readable summary of a result dataset")
    p.add_argument("dataset", type=dataset_file(), metavar="FILE.nc", help="any breastcore dataset")
    p.set_defaults(run=run_show)
    q = sub.add_parser("list", help="list the result datasets of a folder with their scene and stage")
    q.add_argument("folder", nargs="?", default="results", metavar="FOLDER")
    q.set_defaults(run=run_list)


def _labels(ds, dim, limit=40, exclude=()):
    """Names of the entries along ``dim``: its text coordinate, or the text variables along it
    (e.g. ``method/mesh`` per run) other than ``exclude`` (values shown as key numbers, such as
    a verdict); None for numeric or long dimensions."""
    if not 0 < ds.sizes[dim] <= limit:
        return None
    if dim in ds.coords and ds[dim].ndim == 1 and ds[dim].dtype.kind in "fi":   # e.g. c in Pa: values name entries
        units = ds[dim].attrs.get("units", "")
        return [f"{v:g}" + (f" {units}" if units not in ("", "1") else "") for v in ds[dim].values]
    columns = [ds[name].values for name in ds.variables
               if ds[name].dims == (dim,) and ds[name].dtype.kind in "UOS" and name not in exclude
               and not str(ds[name].values[0]).endswith(".nc")]          # file paths name nothing
    if not columns:
        return None
    if dim in ds.coords and ds[dim].dtype.kind in "UOS":
        columns = [ds[dim].values]
    return ["/".join(str(c[i]) for c in columns) for i in range(ds.sizes[dim])]


def describe(ds, pictures=()) -> str:
    """Multi-line summary: what the dataset is, its parameters, key numbers and provenance.

    A patient summary or an identification starts with what a clinician reads first
    (:func:`breastcore.report.clinical.clinical_lines`: the fit verdict, the estimate with its
    95 % intervals, measured against fitted in mm, cm² and ml, and ``pictures``). Key numbers
    are printed to 4 significant digits, each with its units and the names of the entries
    along its dimensions.
    """
    import numpy as np

    from breastcore.model.parameters import PARAMETER_INFO

    a = ds.attrs
    lines = [f"{a.get('title', 'dataset')}  [stage: {a.get('stage', '?')}]"]
    dims = ", ".join(f"{k}={v}" for k, v in ds.sizes.items())
    lines.append(f"  dimensions: {dims}")
    params = json.loads(a.get("parameters", "{}") or "{}")
    if params:
        def shown(k, v):
            units = f" {PARAMETER_INFO[k].units}" if k in PARAMETER_INFO else ""
            return f"{k}={v:.6g}{units}" if isinstance(v, (int, float)) else f"{k}={v}"
        lines.append("  parameters: " + ", ".join(shown(k, v) for k, v in params.items()))
    clinical = a.get("scene_kind") == "patient" or a.get("stage") == "identify"
    if clinical:
        from breastcore.report.clinical import clinical_lines
        lines += clinical_lines(ds, pictures)
    keys = _SCENE_KEY_NUMBERS.get(a.get("scene_kind")) or _KEY_NUMBERS.get(a.get("stage"), [])
    if clinical:
        keys = [k for k in keys if k not in ("estimate", "interval_low", "interval_high", "determined")]
        if keys:
            lines.append("  solver diagnostics of the final shapes:" if a.get("stage") == "scene" else "  details:")
    for name in keys:
        if name in ds:
            var = ds[name]
            lines.append(f"  {name} [{var.attrs.get('units', '')}] ({var.attrs.get('long_name', '')})"
                         + (f", by {' x '.join(var.dims)}" if var.dims else "") + ":")
            for dim in var.dims:
                labels = _labels(ds, dim, exclude=keys)
                if labels:
                    lines.append(f"      {dim}: {', '.join(labels)}")
            values = np.array2string(np.asarray(var.values), threshold=200, max_line_width=100,
                                     formatter={"float_kind": "{:.4g}".format})
            lines.append("      " + values.replace("\n", "\n      "))
    lines += _worth(ds, verdict=not clinical)
    if "success" in a:                          # the optimiser's flag: what the estimate is worth is the verdict
        lines.append(f"  optimiser stopping test met: {'yes' if int(a['success']) else 'no'}")
    for key in ("message", "mesh_level", "solver", "method", "measurement_set", "outcome_counts",
                "guess_outcome_counts", "scene", "source", "choice", "rule"):
        if key in a:
            lines.append(f"  {key}: {a[key]}")
    if "breastcore_version" in a:
        lines.append(f"  provenance: breastcore {a.get('breastcore_version')} (source {a.get('source_hash')}), "
                     f"config {a.get('config_hash')}, created {a.get('created')}")
    else:
        lines.append("  provenance: none (not written by breastcore)")
    return "\n".join(lines)


def _worth(ds, verdict=True) -> list:
    """Lines saying what an estimate is worth: its fit verdict, undetermined parameters, input notes."""
    a, lines = ds.attrs, []
    if "verdict" in a and verdict:
        lines.append(f"  fit verdict: {a['verdict']}: {a.get('verdict_message', '')}")
    if "determined" in ds and "parameter" in ds["determined"].dims and ds["determined"].ndim == 1:
        from breastcore.inverse.uncertainty import UNDETERMINED, undetermined
        loose = undetermined(ds["parameter"].values, ds["determined"].values)
        if loose:
            lines.append(f"  {UNDETERMINED}: {', '.join(loose)}")
        if "limit" in ds:
            from breastcore.inverse.uncertainty import UNSEEN, at_limit
            ends = at_limit(ds["parameter"].values, ds["limit"].values)
            if ends:
                lines.append(f"  {UNSEEN}: {', '.join(ends)}")
    if "sliding_margin" in ds and ds["sliding_margin"].ndim == 0:
        lines.append(f"  sliding margin c/(ρ g V/|Γ_B|): {float(ds['sliding_margin']):.4g}")
    if a.get("regime_warning"):
        lines.append(f"  WARNING: {a['regime_warning']}")
    for note in json.loads(a.get("input_notes", "[]") or "[]"):
        lines.append(f"  input note: {note}")
    return lines


def run_show(args):
    from breastcore.io.datasets import open_dataset
    ds = open_dataset(args.dataset)
    folder = Path(args.dataset).parent
    pictures = sorted(folder.glob("shape_*.png")) if ds.attrs.get("scene_kind") == "patient" else []
    print(describe(ds, pictures))


def scenes_by_dataset(summaries) -> dict:
    """Resolved path of each stage dataset -> the scenes whose summary lists it.

    ``summaries``: ``(path, attrs)`` of scene summaries at ``RESULTS/scenes/NAME/summary.nc``;
    their ``datasets`` attribute (JSON) holds paths relative to ``RESULTS``.
    """
    users = {}
    for path, attrs in summaries:
        root = Path(path).parent.parent.parent
        try:
            datasets = json.loads(attrs.get("datasets", "[]"))
        except ValueError:                      # not ours, or damaged: it names no dataset
            datasets = []
        for relative in datasets:
            users.setdefault((root / relative).resolve(), []).append(attrs.get("scene", "?"))
    return users


def run_list(args):
    import xarray as xr

    folder = Path(args.folder)
    if not folder.is_dir():
        raise UsageError(f"no such folder {str(folder)!r}")
    found = []
    for path in sorted(folder.rglob("*.nc")):
        try:
            with xr.open_dataset(path) as ds:
                found.append((path, dict(ds.attrs)))
        except (OSError, ValueError):
            found.append((path, None))
    summaries = [(p, a) for p, a in found if a and a.get("stage") == "scene"]
    users = scenes_by_dataset(summaries)
    unknown = "-" if summaries else "?"         # no summary below FOLDER: the scenes are unknown
    rows = []
    for path, a in found:
        if a is None:
            rows.append((str(path), "unreadable", "", "", ""))
            continue
        scenes = a.get("scene") or ",".join(sorted(set(users.get(path.resolve(), [])))) or unknown
        rows.append((str(path), a.get("stage", "?"), scenes, a.get("mesh_level", ""), a.get("created", "")))
    width = max((len(r[0]) for r in rows), default=4)
    scene_width = max([len(r[2]) for r in rows] + [5])
    print(f"{'file':<{width}}  {'stage':<12} {'scene':<{scene_width}}  {'mesh':<11} created")
    for r in rows:
        print(f"{r[0]:<{width}}  {r[1]:<12} {r[2]:<{scene_width}}  {r[3]:<11} {r[4]}")
    if not rows:
        print(f"(no datasets under {folder})")
    elif not summaries:
        print(f"(scene '?': no scene summary under {folder}; list the whole results folder to see the scenes)")
