"""Write ``docs/datasets.md`` from real result datasets: every variable, dims, units, meaning.

``python -m breastcore.report.schema_doc FOLDER`` prints the page for the datasets under FOLDER.
``docs/datasets.md`` is rendered from the test workflow's datasets (see ``INTRO``), and
:func:`documented_schema` reads the page back, so that tests can hold every dataset of a
run to it.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import xarray as xr

from breastcore import STAGES as _COMPUTE_STAGES

#: The stages documented, in the page's order: the compute stages, then the scene summaries.
STAGES = (*_COMPUTE_STAGES, "scene")
_ROW = re.compile(r"^\| `(?P<name>[^`]+)` (?:coordinate)? *\| \((?P<dims>[^)]*)\) \| `(?P<units>[^`]*)` \|")

INTRO = """# Result datasets

Every stage of the workflow (and every `breastcore` command) writes one netCDF file
through xarray, atomically (temporary name, then rename). Every variable carries
CF-style `units` and `long_name`; indices are 0-based; coordinates are in the torso
frame (x lateral, y anterior, z superior; the torso plane is y = 0). Where one
variable mixes quantities along a dimension (the six parameters, the five
measurements) its `units` attribute lists the unit of each entry in order,
comma-separated (`m, m, Pa, Pa, Pa, Pa`), and a coordinate (`parameter_units`,
`quantity_units`) holds them one per entry. Such a list is not a UDUNITS string, on
purpose: a CF unit library (cf-units, pint-xarray) refuses it rather than read a
product (a space-separated `m m Pa Pa Pa Pa` would parse as m²·Pa⁴); take each
entry's unit from the coordinate.

Global attributes of every dataset: `stage`, `title`, `breastcore_version`,
`source_hash` (of the package code), `config_hash` (hash of the job's spec),
`parameters` (JSON), `created`, `Conventions`; stage-specific ones are listed below. A scene
summary's `datasets` attribute (JSON) lists the stage datasets the scene is computed from, as
paths relative to the results folder; `breastcore list` uses it to name the scenes that each
shared mesh, solve or identification serves.

The `problem` attribute (JSON, `breastcore.problem.ProblemSpec`) of the `solve`, `measure`
(synthetic data only), `identify`, `sensitivity`, `stability`, `extreme`, `calibrate` and
`uniqueness` datasets is the problem they were computed with: `parameters` (Λ and the
constants ρ, g, c, δ, t_s, θ_D; an identification's initial guess, a calibration job's
truth), `solver` (every `SolverOptions` field), `postures` (name and angle),
`measurement_set` and `identification` (every `IdentificationOptions` field, the warm-start
radius included; null where nothing is identified). Later stages rebuild their
model from it and from nothing else: a sensitivity re-identifies exactly the problem of its
identification, on the mesh the identification dataset keeps in `model_reference_position`.
Reading a spec with a missing or unknown field is an error, never a default.

This page is generated from the datasets of the end-to-end test workflow of
`tests/pipeline/test_workflow.py` (`TINY`: every stage and scene kind; its synthetic scene has
`sensitivity: both` and `tables: [levels]`, so that the finite matrices and the
discretisation error appear) by `breastcore.report.schema_doc.render`. A test fails when the page is
stale; `BREASTCORE_WRITE_DATASETS_DOC=1 pytest tests/pipeline/test_workflow.py` rewrites it. A variable
marked "(some datasets only)" is absent from some datasets of its stage, e.g. a patient's
measurements have no truth.
"""


def describe_stage(variables: dict, attrs: set, title: str, stage: str) -> str:
    rows = [f"## `{stage}`", "", title, "",
            "| variable | dimensions | units | meaning |", "| --- | --- | --- | --- |"]
    for name in sorted(variables):
        dims, units, long_name, coord = variables[name]
        meaning = long_name.replace("|", "\\|")          # a literal bar would end the table cell
        rows.append(f"| `{name}` {'coordinate' if coord else ''} | ({', '.join(dims) or 'scalar'}) | `{units}` "
                    f"| {meaning} |")
    extra = sorted(attrs - {"stage", "title", "breastcore_version", "source_hash", "config_hash",
                            "parameters", "created", "Conventions"})
    rows += ["", "Stage attributes: " + ", ".join(f"`{k}`" for k in extra) + "." if extra else "", ""]
    return "\n".join(rows)


def section_of(ds) -> str:
    """The page section that documents ``ds``: its stage, or ``scene (KIND)`` for a scene summary."""
    stage = ds.attrs.get("stage")
    return stage if stage != "scene" else f"scene ({ds.attrs.get('scene_kind')})"


def documented_schema(text: str) -> dict:
    """``{section: {variable: (dims tuple, units)}}`` read back from the page's tables."""
    schema, section = {}, None
    for line in text.splitlines():
        if line.startswith("## `"):
            section = schema.setdefault(line[4:].rstrip("`"), {})
        elif section is not None and (row := _ROW.match(line)):
            dims = tuple(d.strip() for d in row["dims"].split(",")) if row["dims"] != "scalar" else ()
            section[row["name"]] = (dims, row["units"])
    return schema


def render(folder) -> str:
    """The page, from every dataset under ``folder``: one section per stage (scene summaries
    per kind), the union of their variables, and the stage attributes."""
    found = {}                                     # section -> (variables, attrs, title), union over files
    files, uses = {}, {}                           # datasets per section; datasets holding each variable
    for path in sorted(Path(folder).rglob("*.nc")):
        with xr.open_dataset(path) as ds:
            if ds.attrs.get("stage") not in STAGES:
                continue
            key = section_of(ds)
            variables, attrs, _ = found.setdefault(key, ({}, set(), ds.attrs.get("title", "")))
            files[key] = files.get(key, 0) + 1
            for name, var in ds.variables.items():
                variables.setdefault(name, (var.dims, var.attrs.get("units", ""), var.attrs.get("long_name", ""),
                                            name in ds.coords))
                uses[key, name] = uses.get((key, name), 0) + 1
            attrs.update(ds.attrs)
    for key, (variables, _, _) in found.items():   # e.g. a patient's measurements have no truth
        for name, (dims, units, long_name, coord) in variables.items():
            if uses[key, name] < files[key]:
                variables[name] = (dims, units, f"{long_name} (some datasets only)", coord)
    sections = [describe_stage(*found[key], key) for key in sorted(found, key=lambda k: (STAGES.index(k.split()[0]), k))]
    return "\n".join([INTRO, *sections]) + "\n"


def main(argv=None):
    print(render((argv or sys.argv[1:] or ["results"])[0]), end="")


if __name__ == "__main__":
    main()
