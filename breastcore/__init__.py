"""breastcore: breast biomechanics identified from 15 tape measurements.

The model and method follow Lopes, Clain & Ramires Fernandes, "Parameter
identification method for breast biomechanical numerical model"; where the paper
is silent, ``shared/spec/model.md`` fixes the definitions (see README).
"""

from __future__ import annotations

import functools

__version__ = "0.1.0"


#: The workflow's compute stages: one module each in :mod:`breastcore.stages`.
STAGES = ("mesh", "solve", "measure", "identify", "sensitivity", "stability", "extreme", "calibrate", "uniqueness")


def stage_hash(stage: str, root=None) -> str:
    """:func:`source_hash` of what the script of compute stage ``stage`` imports.

    The stage module (``breastcore.stages.<stage>``) with the modules it imports, and
    ``logs`` and ``keys``, which every stage script imports. An edit of
    ``stability.py`` changes the hash of the stability stage only; one of
    ``identify.py`` those of the stages that import it (identify, sensitivity, extreme).
    """
    if stage not in STAGES:
        raise ValueError(f"unknown stage {stage!r}; stages: {', '.join(STAGES)}")
    return source_hash(f"stages.{stage}", "pipeline.logs", "pipeline.keys", root=root)


def source_hash(*entries: str, root=None) -> str:
    """SHA-256 (first 12 hex digits) of the package's code.

    Snakemake does not see edits in imported modules; rules take this hash as a
    param so that changed code reruns what it affects.

    Parameters
    ----------
    *entries : str
        Modules of the package (``"pipeline"``): hash only these and the modules they
        import, directly or not, plus ``__init__``. The compute rules use it so that
        an edit of the report code does not rerun the solves. Without entries:
        every ``.py`` file.
    root : path, optional
        The package folder to hash (default: this package's; tests hash edited copies).
    """
    import hashlib
    from pathlib import Path

    root = Path(__file__).parent if root is None else Path(root)
    paths = _imported_modules(root, entries) if entries else sorted(root.rglob("*.py"))
    digest = hashlib.sha256()
    for path in paths:
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def _imported_modules(root, entries):
    """Sorted paths of ``__init__``, ``entries`` and the package modules they import, transitively.

    Follows ``from . import x``, ``from .x import y``, ``from ..x import y``,
    ``from breastcore(.x) import y`` and ``import breastcore.x``, at any depth of the
    code (imports inside functions too); a submodule brings its packages'
    ``__init__`` files.
    """
    import ast

    def path_of(parts):
        module, package = root.joinpath(*parts).with_suffix(".py"), root.joinpath(*parts, "__init__.py")
        return module if parts and module.exists() else package if package.exists() else None

    def package_of(path):                                    # x.py → [], sub/y.py and sub/__init__.py → [sub]
        return list(path.relative_to(root).parts[:-1])

    def targets(node, package):
        if isinstance(node, ast.Import):
            return [a.name.split(".")[1:] for a in node.names if a.name.startswith("breastcore.")]
        if not isinstance(node, ast.ImportFrom):
            return []
        if node.level:
            base = package[:len(package) - (node.level - 1)] + (node.module.split(".") if node.module else [])
        elif node.module == "breastcore" or (node.module or "").startswith("breastcore."):
            base = node.module.split(".")[1:]
        else:
            return []
        return [base] + [base + [a.name] for a in node.names]

    seen, todo = set(), [e.split(".") for e in entries]
    for parts in todo:
        if path_of(parts) is None:
            raise ValueError(f"no module {'.'.join(parts)!r} in the package")
    while todo:
        parts = todo.pop()
        for depth in range(len(parts) + 1):                  # the packages' __init__ run first
            path = path_of(parts[:depth])
            if path is None or path in seen:
                continue
            seen.add(path)
            package = package_of(path)
            for node in _import_statements(path.read_text()):
                todo.extend(t for t in targets(node, package) if path_of(t) is not None)
    return sorted(seen | {root / "__init__.py"})


@functools.lru_cache(maxsize=1024)
def _import_statements(source: str):
    """The import statements of a module's source, parsed once per text: the workflow hashes nine stages at start-up."""
    import ast

    return tuple(n for n in ast.walk(ast.parse(source)) if isinstance(n, (ast.Import, ast.ImportFrom)))
