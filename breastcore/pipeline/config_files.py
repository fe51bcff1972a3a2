"""Reading the workflow's YAML config files, with one-line errors: syntax, repeated keys, exponents."""

from __future__ import annotations

import json
import re
from pathlib import Path

import yaml

#: A number in exponent form, which YAML 1.1 reads as text unless written like 1.0e+3.
_EXPONENT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


class ConfigError(ValueError):
    """An invalid configuration; the message names the key and the problem."""


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
