"""Validation of the workflow's ``config.yaml``: schema, defaults and physical checks.

Called by the ``Snakefile`` before any job runs. Errors are one line that names the
key, e.g. ``config key scenes.alice.postures.standing.volume: -5 is not > 0``.
"""

from __future__ import annotations

import copy
import math
import os
import warnings
from pathlib import Path

import jsonschema
import yaml

from breastcore.model.mesh import LEVEL_MESH_SIZE
from breastcore.model.parameters import IDENTIFIED
from breastcore.model.postures import PAPER_POSTURES, PostureError, parse_posture
from breastcore.pipeline.config_files import _EXPONENT, ConfigError

#: The workflow's schema, beside the package (the Snakefile passes its own path).
DEFAULT_SCHEMA = Path(__file__).resolve().parents[2] / "workflow" / "schemas" / "config.schema.yaml"
SCENE_KINDS = ("synthetic", "patient", "forward", "stability", "calibration")


def load_schema(path) -> dict:
    return yaml.safe_load(Path(path).read_text())


def _resolve(schema, root):
    while "$ref" in schema:
        name = schema["$ref"].split("/")[-1]
        schema = {**root["definitions"][name], **{k: v for k, v in schema.items() if k != "$ref"}}
    return schema


def fill_defaults(instance, schema, root):
    """Insert each missing key that has a ``default``, recursively."""
    schema = _resolve(schema, root)
    if not isinstance(instance, dict):
        return instance
    for key, sub in schema.get("properties", {}).items():
        sub = _resolve(sub, root)
        if key not in instance and "default" in sub:
            instance[key] = copy.deepcopy(sub["default"])
        if key in instance:
            fill_defaults(instance[key], sub, root)
    return instance


def _check(instance, schema, root, where):
    validator = jsonschema.Draft7Validator({**schema, "definitions": root["definitions"]})
    error = next(iter(sorted(validator.iter_errors(instance), key=lambda e: list(e.absolute_path))), None)
    if error is not None:
        path = ".".join([where, *(str(p) for p in error.absolute_path)]).strip(".")
        message = error.message
        if error.validator == "additionalProperties":
            message = "unknown key: " + message.split("(")[-1].rstrip(")").replace(" was unexpected", "")
        if error.validator == "type" and isinstance(error.instance, str) and _EXPONENT.fullmatch(error.instance.strip()):
            message += (" (YAML reads a number with an exponent as a number only with a decimal point and a signed "
                        "exponent: write 1.0e+3, not 1e3 or 1.0e3)")
        raise ConfigError(f"config key {path or '<top>'}: {message}")


def _finite(value, where):
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"config key {where}: {value} is not a finite number")
    if isinstance(value, dict):
        for k, v in value.items():
            _finite(v, f"{where}.{k}" if where else str(k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _finite(v, f"{where}[{i}]")


def _levels(levels, where):
    for level in levels:
        if level not in LEVEL_MESH_SIZE:
            raise ConfigError(f"config key {where}: unknown mesh level {level!r}; known: {', '.join(LEVEL_MESH_SIZE)}")


def _postures(texts, where):
    try:
        names = [parse_posture(t).name for t in texts]
    except PostureError as err:
        raise ConfigError(f"config key {where}: {err}") from None
    if len(set(names)) != len(names):
        raise ConfigError(f"config key {where}: repeated posture in {names}")


def _patient_posture(key, values, where):
    """A patient's posture key is a name: one of the paper's, or any name with ``angle:``."""
    if "=" in key:
        name, _, angle = key.partition("=")
        raise ConfigError(f"config key {where}: a patient's posture key is a name; give the angle inside it: "
                          f"{name.strip()}: {{angle: {angle.strip()}, volume: ..., ...}}")
    if "angle" not in values and key not in PAPER_POSTURES:
        raise ConfigError(f"config key {where}: unknown posture {key!r}; known: {', '.join(PAPER_POSTURES)}, "
                          f"or any name with its forward-bend angle as angle: DEGREES")
    _postures([key if "angle" not in values else f"{key}={values['angle']}"], where)


def _patient_values(scene, where):
    """Refuse values no shape of the model produces (unless allow_implausible), naming rule and values."""
    from breastcore.inverse.measurements import MeasurementError
    from breastcore.io.patient import ImplausibleMeasurements, patient_from_dict
    try:
        with warnings.catch_warnings():                 # inconsistent values are run, and flagged by the job
            warnings.simplefilter("ignore")
            patient_from_dict({"measurement_set": scene["measurement_set"], "units": scene["units"],
                               "postures": scene["postures"]}, allow_implausible=scene["allow_implausible"])
    except ImplausibleMeasurements as err:              # its advice names the config key that runs the values
        raise ConfigError(f"config key {where}.postures: {err.advice(f'{where}.allow_implausible: true')}") from None
    except MeasurementError as err:
        raise ConfigError(f"config key {where}.postures: {err}") from None


def _cap(values, where):
    if values.get("H", 0) >= values.get("R", 1):
        raise ConfigError(f"config key {where}.H: H = {values['H']} m must be < R = {values['R']} m")


def _fixed_iterations(scene, methods, where):
    if scene["identification"].get("fixed_iterations") and any(m != "gauss-newton" for m in methods):
        raise ConfigError(f"config key {where}.identification.fixed_iterations: applies to gauss-newton only, "
                          f"and this scene runs {', '.join(sorted(set(methods)))}")


def _calibration(scene, where):
    """The levels and postures of a calibration scene name ones it has (its schema checks the numbers)."""
    _levels(scene["levels"], f"{where}.levels")
    for key in ("reference", "compare_level", "probe_level", "jacobian_level", "truth_mesh"):
        _levels([scene[key]], f"{where}.{key}")
    _levels(scene["identify_meshes"], f"{where}.identify_meshes")
    if scene["reference"] in scene["levels"]:
        raise ConfigError(f"config key {where}.levels: lists the reference level {scene['reference']!r}, which every "
                          f"level is compared with")
    if scene["compare_level"] not in scene["levels"]:
        raise ConfigError(f"config key {where}.compare_level: {scene['compare_level']!r} is not one of levels "
                          f"({', '.join(scene['levels'])})")
    if scene["jacobian_level"] not in (*scene["levels"], scene["reference"]):
        raise ConfigError(f"config key {where}.jacobian_level: {scene['jacobian_level']!r} is neither one of levels "
                          f"nor the reference")
    _postures(scene["postures"], f"{where}.postures")
    if scene["det_F_posture"] not in [parse_posture(t).name for t in scene["postures"]]:
        raise ConfigError(f"config key {where}.det_F_posture: {scene['det_F_posture']!r} is not one of postures")
    _cap(scene["truth"], f"{where}.truth")
    _fixed_iterations(scene, [scene["identification"]["method"]], where)


def validate_config(config, schema_path) -> dict:
    """Validated copy of ``config`` with every default filled in. Raises ConfigError."""
    root = load_schema(schema_path)
    config = copy.deepcopy(dict(config or {}))
    _finite(config, "")
    _check(config, root, root, "")
    fill_defaults(config, root, root)
    if os.path.normpath(config["results"].strip()) in (".", "/", "//"):
        raise ConfigError(f"config key results: {config['results']!r} is empty, the working folder or the file-system root; "
                          f"give a folder such as 'results'")
    if not config["scenes"]:
        raise ConfigError("config key scenes: no scene, so nothing to compute; see config.yaml for examples")
    unknown = [n for n in config["run_scenes"] if n not in config["scenes"]]
    if unknown:
        raise ConfigError(f"config key run_scenes: unknown scene {unknown[0]!r}; scenes: {', '.join(config['scenes'])}")
    for name, scene in config["scenes"].items():
        where = f"scenes.{name}"
        kind = scene.get("kind")
        if kind not in SCENE_KINDS:
            raise ConfigError(f"config key {where}.kind: must be one of {', '.join(SCENE_KINDS)}, got {kind!r}")
        if kind == "patient" and not scene.get("postures"):
            raise ConfigError(f"config key {where}.postures: a patient scene needs measurements")
        schema = root["definitions"][kind]
        _check(scene, schema, root, where)
        fill_defaults(scene, schema, root)
        if kind == "synthetic":
            for item in scene["methods"]:
                fill_defaults(item, root["definitions"]["synthetic"]["properties"]["methods"]["items"], root)
            names = [m["name"] for m in scene["methods"]]
            if len(set(names)) != len(names):
                raise ConfigError(f"config key {where}.methods: repeated method name in {names}")
            if scene["truth_mesh"] != "same":
                _levels([scene["truth_mesh"]], f"{where}.truth_mesh")
            elif "levels" in scene.get("tables", []):
                raise ConfigError(f"config key {where}.tables: 'levels' compares each level with the truth mesh, "
                                  f"and truth_mesh 'same' has none (every gap would be 0)")
            _levels(scene["meshes"], f"{where}.meshes")
            for i, method in enumerate(scene["methods"]):
                _levels(method.get("meshes", []), f"{where}.methods[{i}].meshes")
            _postures(scene["postures"], f"{where}.postures")
            _cap(scene["truth"], f"{where}.truth")
            _fixed_iterations(scene, [m.get("method", "lm") for m in scene["methods"]], where)
        elif kind == "patient":
            _levels([scene["mesh"]], f"{where}.mesh")
            for posture, values in scene["postures"].items():
                _patient_posture(posture, values, f"{where}.postures.{posture}")
                missing = [q for q in ("volume", "area", "height", "frontal_depth", "back_depth") if q not in values]
                if missing:
                    raise ConfigError(f"config key {where}.postures.{posture}: missing {', '.join(missing)}")
            _patient_values(scene, where)
            if 5 * len(scene["postures"]) < len(IDENTIFIED):
                raise ConfigError(f"config key {where}.postures: one posture gives 5 measurements for "
                                  f"{len(IDENTIFIED)} parameters; measure at least two postures")
            _cap(scene["initial"], f"{where}.initial")
            _fixed_iterations(scene, [scene["identification"]["method"]], where)
        elif kind == "stability":
            _levels(scene["meshes"], f"{where}.meshes")
            _postures(scene["grid"]["posture"], f"{where}.grid.posture")
        elif kind == "calibration":
            _calibration(scene, where)
        else:
            _levels([scene["mesh"]], f"{where}.mesh")
            _postures(scene["postures"], f"{where}.postures")
            _cap(scene["parameters"], f"{where}.parameters")
    return config
