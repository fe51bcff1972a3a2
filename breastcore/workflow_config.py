"""Validation of the workflow's ``config.yaml``: schema, defaults and physical checks.

Called by the ``Snakefile`` before any job runs. Errors are one line that names the
key, e.g. ``config key scenes.alice.postures.standing.volume: -5 is not > 0``.
"""

from __future__ import annotations

import contextlib
import copy
import json
import math
import os
import re
import warnings
from pathlib import Path

import jsonschema
import yaml

from .mesh import LEVEL_MESH_SIZE
from .parameters import IDENTIFIED
from .postures import PAPER_POSTURES, PostureError, parse_posture

SCENE_KINDS = ("synthetic", "patient", "forward", "stability", "calibration")


#: A number in exponent form, which YAML 1.1 reads as text unless written like 1.0e+3.
_EXPONENT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


class ConfigError(ValueError):
    """An invalid configuration; the message names the key and the problem."""


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


def _repeated_key(node, where="", seen=None):
    """Raise ConfigError at the first scalar key given twice in one mapping of a YAML node tree.

    Merge keys (``<<``) are left to YAML, which applies them all; an alias met again is
    not walked twice.
    """
    seen = set() if seen is None else seen
    if id(node) in seen:
        return
    seen.add(id(node))
    if isinstance(node, yaml.MappingNode):
        lines = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = (key_node.tag, key_node.value)
            path = f"{where}.{key_node.value}" if where else str(key_node.value)
            line = key_node.start_mark.line + 1
            if key in lines:
                raise ConfigError(f"config key {path}: given twice, at lines {lines[key]} and {line} "
                                  f"of {key_node.start_mark.name}; YAML would silently keep the last")
            lines[key] = line
            _repeated_key(value_node, path, seen)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _repeated_key(item, f"{where}[{i}]", seen)


def _syntax_error(path, err: yaml.YAMLError) -> ConfigError:
    """One line naming the file, line and column of a YAML syntax error, and the problem."""
    mark = getattr(err, "problem_mark", None)
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    if "'\\t'" in problem:                       # PyYAML's words for a tab: name it plainly
        problem = "a tab, which YAML does not allow as indentation (indent with spaces)"
    where = f", line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    context, context_mark = getattr(err, "context", None), getattr(err, "context_mark", None)
    if context and context_mark is not None and context_mark.line != getattr(mark, "line", None):
        problem += f" ({context} that starts at line {context_mark.line + 1})"
    return ConfigError(f"config file {path}{where}: {problem}")


def check_config_files(paths) -> None:
    """Refuse a config file that is not valid YAML, or that repeats a key.

    Snakemake's own loader says only "Config file is not valid JSON or YAML", with
    neither the file nor the line; and it keeps the last of two equal keys (e.g. two
    scenes of one name), as YAML does, silently.

    Parameters
    ----------
    paths : iterable of str or Path
        Config files, read as Snakemake reads them: JSON first, then YAML (so JSON
        indented with tabs, which YAML refuses, is accepted).

    Raises
    ------
    ConfigError
        Naming the file, line and column of a syntax error, or the repeated key and
        both of its lines.
    """
    for path in paths:
        with open(path, encoding="utf-8") as stream:          # a stream: the marks carry its name
            try:
                tree = yaml.compose(stream, Loader=yaml.SafeLoader)
            except yaml.YAMLError as err:
                stream.seek(0)
                try:
                    json.load(stream)
                except ValueError:
                    raise _syntax_error(path, err) from None
                continue
        _repeated_key(tree)


def _load_config_file(path) -> dict:
    """A config file's content, read as Snakemake reads it (JSON first, then YAML)."""
    text = Path(path).read_text(encoding="utf-8")
    try:
        data = json.loads(text)
    except ValueError:
        data = yaml.safe_load(text)
    return data if isinstance(data, dict) else {}


def _left_out(base, overlay, where):
    """Key paths (tuples) of the mapping ``base`` that the mapping ``overlay`` does not give, recursively."""
    missing = []
    for key, value in base.items():
        path = (*where, key)
        if key not in overlay:
            missing.append(path)
        elif isinstance(value, dict) and isinstance(overlay[key], dict):
            missing += _left_out(value, overlay[key], path)
    return missing


def _null_drops(base, overlay, where=()):
    """Key paths that ``overlay`` sets to null and ``base`` gives: the keys it drops on purpose."""
    drops = []
    for key, value in overlay.items():
        if isinstance(base, dict) and key in base:
            if value is None and base[key] is not None:
                drops.append((*where, key))
            elif isinstance(value, dict):
                drops += _null_drops(base[key], value, (*where, key))
    return drops


def _merge(config, overlay):
    """Snakemake's merge of a config file into the config (``snakemake.utils.update_config``)."""
    for key, value in overlay.items():
        if isinstance(value, dict):
            config[key] = _merge(config[key] if isinstance(config.get(key), dict) else {}, value)
        else:
            config[key] = value
    return config


#: The workflow's schema, beside the package (the Snakefile passes its own path).
DEFAULT_SCHEMA = Path(__file__).resolve().parents[1] / "workflow" / "schemas" / "config.schema.yaml"


def _redefined(base, merged, overlay):
    """Key paths of ``base``'s scenes that ``overlay`` gives again as mappings: such a file is a
    copy of ``base``. A file that gives a section again (``solver``, ``constants``) is an
    overlay, e.g. the constants of another regime over ``config.yaml``'s scenes."""
    def both(tree, key):
        return isinstance(tree, dict) and isinstance(tree.get(key), dict)
    scenes = overlay.get("scenes")
    if not isinstance(scenes, dict):
        return []
    return [("scenes", name) for name, scene in scenes.items()
            if isinstance(scene, dict) and both(base.get("scenes"), name) and both(merged.get("scenes"), name)]


def _omitted(base, merged, overlay):
    """Key paths of ``base``'s top-level keys and scenes, still in ``merged``, that ``overlay`` does not give."""
    out = [(key,) for key in base if key != "scenes" and key in merged and key not in overlay]
    if "scenes" in overlay and not isinstance(overlay["scenes"], dict):     # scenes: null drops them all
        return out
    given = overlay.get("scenes") or {}
    base_scenes, merged_scenes = base.get("scenes"), merged.get("scenes")
    if isinstance(base_scenes, dict) and isinstance(merged_scenes, dict):
        out += [("scenes", name) for name in base_scenes if name in merged_scenes and name not in given]
    return out


def _may_be_null(path, config, root) -> bool:
    """Whether the key at ``path`` may be dropped with null: the schema gives it a default, or it
    is a named entry (a scene, a patient's posture). ``kind``, a patient's ``postures`` and its
    measured values may not: the config would then be refused. ``config`` gives each scene's kind."""
    if root is None:
        return True
    node, nullable = root, True
    for depth, key in enumerate(path):
        if depth == 1 and path[0] == "scenes":
            scene = (config.get("scenes") or {}).get(key)
            node = root["definitions"].get(scene.get("kind")) if isinstance(scene, dict) else None
            if node is None:                          # an unknown kind: validation names it
                return True
            nullable = True
            continue
        node = _resolve(node, root)
        properties = node.get("properties", {})
        if key in properties:
            child = _resolve(properties[key], root)
            nullable = key not in node.get("required", []) and "default" in child
        elif isinstance(node.get("additionalProperties"), dict):
            child, nullable = node["additionalProperties"], True
        else:                                         # a key the schema does not know: validation names it
            return True
        node = child
    return nullable


def _dotted(paths):
    return ", ".join(".".join(map(str, p)) for p in paths)


def check_overlays(base_path, overlay_paths, replace=False, schema_path=None) -> list:
    """Refuse a ``--configfile`` that redefines a scene or section of ``config.yaml`` but
    leaves out some of its keys, or, being then a copy of ``config.yaml``, some of its
    scenes or sections.

    Snakemake merges each ``--configfile`` into ``config.yaml`` key by key, so a key that a
    copy leaves out (a posture, a measured quantity, a whole scene or section) silently
    keeps ``config.yaml``'s value: the copy runs what it no longer says. A file that adds
    scenes of new names and sets top-level keys (``run_scenes``, ``max_starts``) is an
    overlay, merged as usual; that is what the opt-in configs of ``config/`` do; so is one
    that gives a section (``solver``, ``constants``, ``report``) again, which must give every
    key of it. A file that gives one of ``config.yaml``'s scenes again is a copy: it must
    give every key of that scene, and every top-level key and scene of ``config.yaml``, or
    drop them with null. A list is replaced whole, so it cannot leave anything behind.

    Parameters
    ----------
    base_path : str or Path
        The Snakefile's ``configfile`` (``config.yaml``); a missing file counts as empty.
    overlay_paths : sequence of str or Path
        The ``--configfile`` files, in the order Snakemake merges them; each one is
        compared with ``config.yaml`` merged with the files before it.
    replace : bool
        ``--replace-workflow-config``: Snakemake discards ``config.yaml``, so the files are
        compared only with the files before them, and none is a copy of ``config.yaml``.
    schema_path : str or Path, optional
        The config schema (default: the workflow's), which says which keys may be null:
        the refusal says to give the others.

    Returns
    -------
    list of tuple of str
        The key paths that a file sets to ``null`` to drop the key on purpose; the caller
        removes them from the merged config (:func:`drop_keys`).

    Raises
    ------
    ConfigError
        Naming every key left out, the file that gives it and the file that leaves it out.
    """
    sources = [] if replace or not os.path.exists(base_path) else [(str(base_path), _load_config_file(base_path))]
    base = sources[0][1] if sources else {}
    schema_path = DEFAULT_SCHEMA if schema_path is None else schema_path
    root = load_schema(schema_path) if os.path.exists(schema_path) else None
    merged = copy.deepcopy(base)
    drops = []
    for path in overlay_paths:
        overlay = _load_config_file(path)
        path = _shown(path)
        missing = []
        for key, value in overlay.items():
            previous = merged.get(key)
            if not (isinstance(value, dict) and isinstance(previous, dict)):
                continue
            if key == "scenes":                                   # scenes are added; a redefined one is compared
                for name, scene in value.items():
                    if isinstance(scene, dict) and isinstance(previous.get(name), dict):
                        missing += _left_out(previous[name], scene, ("scenes", name))
            else:
                missing += _left_out(previous, value, (key,))
        redefined = _redefined(base, merged, overlay)
        whole = _omitted(base, merged, overlay) if redefined else []
        missing += whole
        if missing:
            raise ConfigError(_left_out_message(missing, whole, redefined, sources, path,
                                                _merge(copy.deepcopy(merged), overlay), root))
        drops += _null_drops(merged, overlay)
        _merge(merged, overlay)
        for drop in drops:
            _pop(merged, drop)
        sources.append((str(path), overlay))
    return drops


def _left_out_message(missing, whole, redefined, sources, path, config, root) -> str:
    """The refusal of :func:`check_overlays`: the keys, where they come from, why they would run, what to do."""
    origins = " and ".join(name for name, tree in sources if any(_gives(tree, m) for m in missing))
    one = len(missing) == 1
    text = (f"config key{'' if one else 's'} {_dotted(missing)}: in {origins} but left out of {path}, which "
            f"Snakemake merges into {origins} key by key, so {origins}'s value{'' if one else 's'} would run")
    if whole:
        base = sources[0][0]
        text += (f" ({path} redefines {base}'s {_dotted(redefined[:1])}: a copy of {base}, which must give or "
                 f"drop each scene and section of it)")
    required = [m for m in missing if not _may_be_null(m, config, root)]
    nullable = [m for m in missing if m not in required]
    if not required:
        return (f"{text}; drop {'it' if one else 'each'} with null in {path} ({nullable[0][-1]}: null), or run "
                f"{path} alone with --replace-workflow-config")
    them = "it" if len(required) == 1 else "them"
    advice = (f"give {them if not nullable else _dotted(required)} in {path} (required: null cannot drop {them})")
    if nullable:
        advice += f"; drop the other{'' if len(nullable) == 1 else 's'} with null ({nullable[0][-1]}: null)"
    return f"{text}; {advice}"


def _shown(path):
    """``path`` relative to the working folder when inside it (Snakemake makes --configfile paths absolute)."""
    relative = os.path.relpath(path)
    return str(path) if relative.startswith("..") else relative


def _gives(tree, keys):
    for key in keys:
        if not isinstance(tree, dict) or key not in tree:
            return False
        tree = tree[key]
    return True


def _pop(config, path):
    node = config
    for key in path[:-1]:
        node = node.get(key) if isinstance(node, dict) else None
    if isinstance(node, dict) and node.get(path[-1], 0) is None:
        del node[path[-1]]


def drop_keys(config, paths) -> None:
    """Remove from ``config``, in place, each key path whose value is null (see :func:`check_overlays`).

    A later file that gave the key a value again keeps it.
    """
    for path in paths:
        _pop(config, path)


@contextlib.contextmanager
def config_errors_exit():
    """Context manager: a :class:`ConfigError` ends the program with its one line and status 1.

    Snakemake prints an exception raised in the Snakefile with the Snakefile's line and
    3-8 ``File "...", line ...`` frames of the code that raised it; a ``SystemExit`` it
    lets through, and Python prints its message alone, on stderr.
    """
    try:
        yield
    except ConfigError as err:
        raise SystemExit(f"ConfigError: {err}") from None


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
    from .measure import MeasurementError
    from .patient import ImplausibleMeasurements, patient_from_dict
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
