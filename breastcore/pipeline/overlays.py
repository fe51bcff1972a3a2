"""Config overlays (``--configfile``): what each overlay redefines, leaves out or drops."""

from __future__ import annotations

import contextlib
import copy
import os

from breastcore.pipeline.config import DEFAULT_SCHEMA, _resolve, load_schema
from breastcore.pipeline.config_files import ConfigError, _load_config_file


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
