"""The key of a workflow job: a short hash of its JSON spec (its output path and config hash)."""

from __future__ import annotations

import hashlib
import json


def spec_key(spec) -> str:
    """Short stable hash of a JSON-able spec."""
    return hashlib.sha1(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:10]
