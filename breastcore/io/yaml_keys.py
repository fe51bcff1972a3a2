"""A key given twice in one YAML mapping, which YAML would resolve silently by keeping the last."""

from __future__ import annotations

import yaml


def repeated_key(node, where="", seen=None):
    """The first scalar key given twice in one mapping of a composed YAML node tree, else None.

    Returns
    -------
    tuple of (str, int, int, str) or None
        The key's dotted path, its first and second line (1-based), and the stream's name.

    Merge keys (``<<``) are left to YAML, which applies them all; an alias met again is not
    walked twice.
    """
    seen = set() if seen is None else seen
    if id(node) in seen:
        return None
    seen.add(id(node))
    children = []
    if isinstance(node, yaml.MappingNode):
        lines = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = (key_node.tag, key_node.value)
            path = f"{where}.{key_node.value}" if where else str(key_node.value)
            line = key_node.start_mark.line + 1
            if key in lines:
                return path, lines[key], line, key_node.start_mark.name
            lines[key] = line
            children.append((value_node, path))
    elif isinstance(node, yaml.SequenceNode):
        children = [(item, f"{where}[{i}]") for i, item in enumerate(node.value)]
    for child, path in children:
        found = repeated_key(child, path, seen)
        if found:
            return found
    return None
