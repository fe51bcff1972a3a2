"""breastcore: breast biomechanics identified from 15 tape measurements.

The model and method follow Lopes, Clain & Ramires Fernandes, "Parameter
identification method for breast biomechanical numerical model"; where the paper
is silent, ``shared/spec/model.md`` fixes the definitions (see README).
"""

from __future__ import annotations

__version__ = "0.1.0"


def source_hash(*entries: str) -> str:
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
    """
    import hashlib
    from pathlib import Path

    root = Path(__file__).parent
    paths = _imported_modules(root, entries) if entries else sorted(root.rglob("*.py"))
    digest = hashlib.sha256()
    for path in paths:
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def _imported_modules(root, entries):
    """Sorted paths of ``__init__``, ``entries`` and the package modules they import, transitively."""
    import ast

    def path_of(name):
        module, package = root / f"{name}.py", root / name / "__init__.py"
        return module if module.exists() else package if package.exists() else None

    seen, todo = set(), list(entries)
    while todo:
        name = todo.pop()
        path = path_of(name)
        if path is None:
            raise ValueError(f"no module {name!r} in {root}")
        if path in seen:
            continue
        seen.add(path)
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                names = [node.module] if node.module else [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("breastcore."):
                names = [node.module.split(".", 1)[1]]
            else:
                continue
            todo.extend(n.split(".")[0] for n in names if path_of(n.split(".")[0]) is not None)
    return sorted(seen | {root / "__init__.py"})
