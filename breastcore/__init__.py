"""breastcore: breast biomechanics identified from 15 tape measurements.

The model and method follow Lopes, Clain & Ramires Fernandes, "Parameter
identification method for breast biomechanical numerical model"; where the paper
is silent, ``shared/spec/model.md`` fixes the definitions (see README).
"""

from __future__ import annotations

__version__ = "0.1.0"


def source_hash() -> str:
    """SHA-256 (first 12 hex digits) of every ``.py`` file of the package.

    Snakemake does not see edits in imported modules; rules take this hash as a
    param so that changed code reruns what it affects.
    """
    import hashlib
    from pathlib import Path

    root = Path(__file__).parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]
