"""Compare two workflow results folders dataset by dataset: identical, wall times aside?

The proof of a refactoring: :func:`compare_results` of the results of one configuration run by the code
before and after it (``breastcore compare A B``)."""

from __future__ import annotations

import os
import re
from collections import Counter, deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

PROVENANCE_ATTRIBUTES = frozenset({"created", "source_hash", "config_hash", "breastcore_version"})
WALL_TIME_WORDS = ("wall", "cpu", "elapsed")
IGNORED_FOLDERS = frozenset({"logs", "benchmarks"})
PATH_PLACEHOLDER = "<results path>"
#: A piece of text ending in ``.nc``: maybe a path (blanks, quotes, brackets and ``,;:=|`` end it).
_NC_TOKEN = re.compile(r"[^\s\"'<>,;:=|()\[\]{}]+\.nc(?!\w)")
_MISSING = object()


class ResultsFolderError(ValueError):
    """A folder that cannot be compared: missing, or without any ``.nc`` dataset."""


@dataclass(frozen=True)
class ComparisonResult:
    """What :func:`compare_results` found: ``identical`` (no difference; no unpaired dataset unless allowed), the
    number of ``pairs``, the ``differences`` (one line each), the unpaired datasets, the ``paired`` paths (A, B)."""

    identical: bool
    pairs: int
    differences: tuple[str, ...]
    unpaired_a: tuple[str, ...]
    unpaired_b: tuple[str, ...]
    paired: tuple[tuple[str, str], ...] = ()


class ResultsFolder:
    """One results folder: its ``.nc`` datasets (relative paths) and the paths its text names."""

    def __init__(self, folder):
        self.root = Path(os.path.abspath(folder))
        self.datasets = {path.relative_to(self.root).as_posix() for path in self.root.rglob("*.nc")
                         if path.is_file() and path.relative_to(self.root).parts[0] not in IGNORED_FOLDERS}
        if not self.datasets:           # also when the folder does not exist
            raise ResultsFolderError(f"{str(folder)!r} is not a folder holding .nc datasets (a results folder)")
        self._resolved = {}

    def resolve(self, text):
        """The dataset of this folder (relative path) that ``text`` names, or None."""
        if text not in self._resolved:
            path = Path(text)
            candidates = [path] if path.is_absolute() else [self.root.parent / path, self.root / path]
            candidates += [self.root.joinpath(*path.parts[start:]) for start in range(1, len(path.parts))]
            relatives = (os.path.relpath(os.path.normpath(c), self.root).replace(os.sep, "/") for c in candidates)
            self._resolved[text] = next((r for r in relatives if r in self.datasets), None)
        return self._resolved[text]

    def mask(self, array):
        """A text array as str with each path to a dataset of this folder replaced by
        :data:`PATH_PLACEHOLDER` (object array, same shape), and the datasets each entry names."""
        texts = [x.decode("utf-8", "replace") if isinstance(x, bytes) else str(x) for x in array.ravel().tolist()]
        masked = np.empty(len(texts), dtype=object)
        masked[:] = [_NC_TOKEN.sub(lambda m: PATH_PLACEHOLDER if self.resolve(m.group()) else m.group(), text)
                     for text in texts]
        named = [[d for d in map(self.resolve, _NC_TOKEN.findall(text)) if d is not None] for text in texts]
        return masked.reshape(array.shape), named


def value_difference(a, b, folders):
    """What differs between two values (array, number or text): a line, or None when exactly equal; and
    the pairs of datasets equal text entries name at the same place (results paths in text are masked)."""
    a, b = np.asarray(a), np.asarray(b)
    kind_a, kind_b = ("text" if x.dtype.kind in "OSU" else x.dtype.kind for x in (a, b))
    if kind_a != kind_b or a.shape != b.shape:
        return f"dtype {a.dtype} shape {a.shape} vs dtype {b.dtype} shape {b.shape}", []
    named_a = named_b = [()] * a.size
    if kind_a == "text":
        (a, named_a), (b, named_b) = folders[0].mask(a), folders[1].mask(b)
    equal = np.asarray((a == b) | (np.isnan(a) & np.isnan(b) if kind_a in "fc" else False), dtype=bool)
    references = [pair for same, x, y in zip(equal.ravel(), named_a, named_b) if same for pair in zip(x, y)]
    differing = int(equal.size - np.count_nonzero(equal))
    summary = f"{differing} of {equal.size} entries differ"
    if not differing:
        return None, references
    if kind_a not in "biuf":            # the first differing entries, from before their first differing character
        x, y = (str(v.ravel()[np.flatnonzero(~equal.ravel())[0]]) for v in (a, b))
        at = max(0, next((i for i, (p, q) in enumerate(zip(x, y)) if p != q), min(len(x), len(y))) - 15)
        return f"{summary}, first from character {at}: {x[at:at + 50]!r} vs {y[at:at + 50]!r}", references
    x, y = a[~equal].astype(float), b[~equal].astype(float)
    with np.errstate(all="ignore"):
        gap, scale = np.abs(x - y), np.maximum(np.abs(x), np.abs(y))
    finite = np.isfinite(gap)
    summary += f", max abs {gap[finite].max():.3g}, max rel {(gap / scale)[finite].max():.3g}" if finite.any() else ""
    summary += f", {np.count_nonzero(~finite)} NaN or inf in one only" if not finite.all() else ""
    return summary, references


def _is_wall_time(name, attrs=None):
    """A wall-clock time: the name contains a word of :data:`WALL_TIME_WORDS`, or the units are ``s``."""
    return any(word in str(name).lower() for word in WALL_TIME_WORDS) or (attrs or {}).get("units") == "s"


class _Comparison:
    """A comparison under way: the pairs found (a dataset in one at most), those to compare, the differences."""

    def __init__(self, folders):
        self.folders, self.a_to_b, self.b_to_a, self.to_compare, self.differences = folders, {}, {}, deque(), []

    def pair(self, a, b, origin):
        """Pair ``a`` with ``b``, to compare; a dataset already paired with another one is a difference."""
        if self.a_to_b.get(a) == b:
            return None
        if a in self.a_to_b or b in self.b_to_a:       # a dataset in two pairs
            return self.differences.append(f"{origin}: names A {a} and B {b} at the same place, but they are "
                                           f"paired with B {self.a_to_b.get(a)} and A {self.b_to_a.get(b)}")
        self.a_to_b[a], self.b_to_a[b] = b, a
        return self.to_compare.append((a, b))

    def pair_same_names(self, prefix=""):
        """Pair the unpaired datasets whose relative path (starting with ``prefix``) is on both sides."""
        for name in sorted(self.folders[0].datasets & self.folders[1].datasets):
            if name.startswith(prefix) and name not in self.a_to_b and name not in self.b_to_a:
                self.pair(name, name, "same name")

    def compare(self, label, what, x, y):
        """Note a difference of two values (or :data:`_MISSING`); pair the datasets they name at the same place."""
        if x is _MISSING or y is _MISSING:
            return self.differences.append(f"{label}: {what}: only in {'A' if y is _MISSING else 'B'}")
        difference, references = value_difference(x, y, self.folders)
        if difference:
            self.differences.append(f"{label}: {what}: {difference}")
        for a, b in references:
            self.pair(a, b, origin=label)

    def compare_attributes(self, label, what, attrs_a, attrs_b):
        """Note the attributes in one only or different (provenance and wall times aside)."""
        for key in sorted(set(attrs_a) | set(attrs_b), key=str):
            if key not in PROVENANCE_ATTRIBUTES and not _is_wall_time(key):
                self.compare(label, f"{what} {key!r}", attrs_a.get(key, _MISSING), attrs_b.get(key, _MISSING))

    def compare_variable(self, label, ds_a, ds_b, name):
        """Note how variable (or coordinate) ``name`` differs between the two datasets."""
        where = f"{label}: variable {name!r}"
        if name not in ds_a.variables or name not in ds_b.variables:
            return self.differences.append(f"{where}: only in {'A' if name in ds_a.variables else 'B'}")
        var_a, var_b = ds_a.variables[name], ds_b.variables[name]
        if _is_wall_time(name, var_a.attrs) and _is_wall_time(name, var_b.attrs):
            return None
        if (name in ds_a.coords) != (name in ds_b.coords):
            self.differences.append(f"{where}: a coordinate in {'A' if name in ds_a.coords else 'B'} only")
        if var_a.dims != var_b.dims:
            return self.differences.append(f"{where}: dims {var_a.dims} vs {var_b.dims}")
        self.compare(label, f"variable {name!r}", var_a.values, var_b.values)
        return self.compare_attributes(label, f"variable {name!r} attribute", var_a.attrs, var_b.attrs)

    def compare_pair(self, a, b):
        """Compare dataset ``a`` of folder A with ``b`` of folder B (relative paths)."""
        import xarray as xr
        label = a if a == b else f"{a} ~ {b}"
        try:
            ds_a, ds_b = (xr.load_dataset(folder.root / name, decode_times=False, decode_timedelta=False)
                          for folder, name in zip(self.folders, (a, b)))
        except Exception as err:        # netCDF4 and xarray raise OSError, ValueError, RuntimeError...
            return self.differences.append(f"{label}: cannot read: {err}")
        self.compare_attributes(label, "attribute", ds_a.attrs, ds_b.attrs)
        for name in sorted(set(ds_a.variables) | set(ds_b.variables), key=str):
            self.compare_variable(label, ds_a, ds_b, name)


def compare_results(folder_a, folder_b, allow_unpaired=False) -> ComparisonResult:
    """Is every dataset of two results folders identical, wall times aside?

    Parameters
    ----------
    folder_a, folder_b : str or Path
        Two results folders; their ``.nc`` files are compared, except under ``logs/``, ``benchmarks/``.
    allow_unpaired : bool
        Datasets paired with none do not make the folders differ (they are still listed).

    Returns
    -------
    ComparisonResult

    Raises
    ------
    ResultsFolderError
        A folder is missing or holds no ``.nc`` dataset.

    Notes
    -----
    Pairing: ``scenes/<scene>/*.nc`` by name; then, recursively, a dataset named by a paired dataset's
    text (text variable or coordinate, attribute, JSON included) with the one named at the same place
    (variable and entry or attribute, occurrence) in the other; last, by same relative path. Paths are
    resolved against the folder's parent (``results/solve/k.nc``), the folder (``solve/k.nc``), then the
    folder with leading components dropped. Identical: the same variables and coordinates (role, dims,
    shape, dtype kind, attributes), values exactly equal (NaN equals NaN, 0.0 equals -0.0). Ignored:

    * wall times: variables whose name contains ``wall``, ``cpu`` or ``elapsed``, or whose ``units``
      are ``s`` in both (the model has no physical time): only their presence is compared;
      attributes whose name contains one of these words;
    * the attributes ``created``, ``source_hash``, ``config_hash``, ``breastcore_version``;
    * results paths in text, replaced by a placeholder: they are compared through the pairing;
    * the encoding (compression, chunks, fill values), the order of variables and attributes.
    """
    comparison = _Comparison((ResultsFolder(folder_a), ResultsFolder(folder_b)))
    comparison.pair_same_names("scenes/")
    while True:                 # a folder without scenes/ (a solve/ folder alone) pairs by path only
        while comparison.to_compare:
            comparison.compare_pair(*comparison.to_compare.popleft())
        comparison.pair_same_names()
        if not comparison.to_compare:
            break
    unpaired_a = tuple(sorted(comparison.folders[0].datasets - set(comparison.a_to_b)))
    unpaired_b = tuple(sorted(comparison.folders[1].datasets - set(comparison.b_to_a)))
    identical = not comparison.differences and (allow_unpaired or not (unpaired_a or unpaired_b))
    return ComparisonResult(identical, len(comparison.a_to_b), tuple(comparison.differences), unpaired_a,
                            unpaired_b, tuple(sorted(comparison.a_to_b.items())))


def render(result: ComparisonResult) -> str:
    """A short text report: pairs and unpaired datasets per stage folder, each difference, a verdict."""
    counts = [Counter(name.split("/")[0] for name in names)
              for names in ([a for a, _ in result.paired], result.unpaired_a, result.unpaired_b)]
    lines = [f"{'stage folder':<14}{'pairs':>7}{'unpaired A':>12}{'unpaired B':>12}"]
    lines += [f"{stage:<14}{counts[0][stage]:>7}{counts[1][stage]:>12}{counts[2][stage]:>12}"
              for stage in sorted(set().union(*counts))]
    lines += [f"unpaired in A: {name}" for name in result.unpaired_a]
    lines += [f"unpaired in B: {name}" for name in result.unpaired_b] + list(result.differences)
    unpaired = len(result.unpaired_a) + len(result.unpaired_b)
    verdict = (f"IDENTICAL: all {result.pairs} dataset pairs are identical in every variable, wall times aside"
               + (f" ({unpaired} unpaired allowed)" if unpaired else "") if result.identical else
               f"DIFFERENT: {len(result.differences)} differences, {unpaired} unpaired, {result.pairs} pairs compared")
    return "\n".join(lines + [verdict])
