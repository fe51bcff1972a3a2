"""Reading the workflow's YAML config files, with one-line errors: syntax, repeated keys, exponents."""

from __future__ import annotations

import json
import re
from pathlib import Path

import yaml

from breastcore.io.yaml_keys import repeated_key

#: A number in exponent form, which YAML 1.1 reads as text unless written like 1.0e+3.
_EXPONENT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


class ConfigError(ValueError):
    """An invalid configuration; the message names the key and the problem."""


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
        found = repeated_key(tree)
        if found:
            path_, first, second, name = found
            raise ConfigError(f"config key {path_}: given twice, at lines {first} and {second} of {name}; YAML "
                              "would silently keep the last")


def _load_config_file(path) -> dict:
    """A config file's content, read as Snakemake reads it (JSON first, then YAML)."""
    text = Path(path).read_text(encoding="utf-8")
    try:
        data = json.loads(text)
    except ValueError:
        data = yaml.safe_load(text)
    return data if isinstance(data, dict) else {}
