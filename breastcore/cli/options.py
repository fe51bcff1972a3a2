"""Argument types and option helpers shared by the sub-commands of the command line.

Numbers and dataset files are checked by the argparse types of this module while the command
line is parsed, before any work: :class:`Bounded` (with :func:`positive_float`,
:func:`non_negative_float`, :func:`fraction`, :func:`positive_int`, :func:`parameter_type`)
and :func:`dataset_file`.
"""

from __future__ import annotations

import argparse
import math
import os
import re
from pathlib import Path

from breastcore.model.parameters import (
    FOLD_ANGLE_RANGE,
    NON_NEGATIVE_PARAMETERS,
    PARAMETER_INFO,
    POSITIVE_PARAMETERS,
    ParameterError,
    Parameters,
)
from breastcore.model.postures import PAPER_POSTURES, PostureError, parse_posture


class UsageError(Exception):
    """Bad command-line input: printed as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)


class Bounded:
    """argparse type: a finite number within a range; anything else is refused in one line.

    Parameters
    ----------
    low : float
        Lower bound of the range.
    high : float, optional
        Upper bound of the range (default: none).
    low_open, high_open : bool
        Exclude the bound itself (``> low`` rather than ``>= low``).
    integer : bool
        Accept integers only (``int(text)``: ``1.5`` and ``1e3`` are refused).

    Attributes
    ----------
    range : str
        The range as ``--help`` states it: ``> 0``, ``>= 0``, ``in (0, 1)``, ``integer >= 1``.

    Notes
    -----
    It is called by argparse while the command line is parsed, so a bad value stops the
    command before any mesh, solve or identification. argparse prefixes the message with
    ``argument OPTION:``, so the message itself names only the value.
    """

    def __init__(self, low, high=None, *, low_open=False, high_open=False, integer=False):
        self.low, self.high, self.low_open, self.high_open, self.integer = low, high, low_open, high_open, integer
        if high is None:
            self.range = f"{'>' if low_open else '>='} {low:g}"
        else:
            self.range = f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
        if integer:
            self.range = f"integer {self.range}"

    def refusal(self) -> str:
        """What a refused value is told: ``must be a finite number in (0, 1)``."""
        return f"must be an {self.range}" if self.integer else f"must be a finite number {self.range}"

    def __call__(self, text):
        try:
            value = int(text) if self.integer else float(text)
        except (TypeError, ValueError):
            value = math.nan
        inside = (math.isfinite(value)
                  and (value > self.low if self.low_open else value >= self.low)
                  and (self.high is None or (value < self.high if self.high_open else value <= self.high)))
        if not inside:
            raise argparse.ArgumentTypeError(f"{self.refusal()}, got {text!r}")
        return value


def positive_float() -> Bounded:
    """A finite float > 0 (tolerances, sizes, moduli that must not vanish)."""
    return Bounded(0.0, low_open=True)


def non_negative_float() -> Bounded:
    """A finite float >= 0 (a modulus or coefficient that may be switched off with 0)."""
    return Bounded(0.0)


def fraction(zero=True) -> Bounded:
    """A fraction in [0, 1), or in (0, 1) with ``zero=False`` (a relative step or tolerance)."""
    return Bounded(0.0, 1.0, low_open=not zero, high_open=True)


def positive_int() -> Bounded:
    """An integer >= 1 (counts: iterations, processes)."""
    return Bounded(1, integer=True)


def parameter_type(name) -> Bounded:
    """The range :class:`~breastcore.model.parameters.Parameters` accepts for parameter ``name``.

    ``H < R`` involves two options and is checked once both are known, by
    :func:`parameters_from_args`.
    """
    if name in POSITIVE_PARAMETERS:
        return positive_float()
    if name in NON_NEGATIVE_PARAMETERS:
        return non_negative_float()
    if name == "fold_angle":
        return Bounded(*FOLD_ANGLE_RANGE, low_open=True)
    raise KeyError(f"no range known for parameter {name!r}")


def parameter_assignments(names):
    """argparse type: ``NAME=VALUE,...`` for some of ``names``, each value in its parameter's range.

    Returns the text unchanged (it is parsed again with the defaults by the command), so that
    an unknown name, a repeated one or a bad value stops the command while it is parsed.
    """
    def convert(text):
        seen = set()
        for item in filter(None, (t.strip() for t in text.split(","))):
            key, equals, value = (t.strip() for t in item.partition("="))
            key = key.replace("-", "_")
            if not equals:
                raise argparse.ArgumentTypeError(f"{item!r} is not NAME=VALUE")
            if key not in names:
                raise argparse.ArgumentTypeError(f"unknown parameter {key!r} in {item!r}; known: {', '.join(names)}")
            if key in seen:
                raise argparse.ArgumentTypeError(f"{key} is given twice in {text!r}")
            seen.add(key)
            try:
                parameter_type(key)(value)
            except argparse.ArgumentTypeError as err:
                raise argparse.ArgumentTypeError(f"{key}={value}: {err}") from None
        return text
    return convert


def posture_text(text):
    """argparse type: ``NAME`` (a paper posture) or ``NAME=ANGLE`` with the angle in [0, 90] degrees.

    Returns the text unchanged (:func:`postures_from_args` parses it, and checks that no
    name is repeated across the ``--posture`` options).
    """
    try:
        parse_posture(text)
    except PostureError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return text


def writable_path():
    """Argument type: a file path whose folder exists (or can be made) and takes a new file.

    Checked before any work: an empty name, a folder, or anything that is not a regular file
    (a device such as /dev/null, a pipe) is refused, because the output is written under a
    temporary name and renamed over the path, which would replace that device. The folder (or
    its nearest existing ancestor) is probed by creating and removing a file in it, since
    permission bits alone do not tell (a read-only mount, /proc).
    """
    def convert(text):
        path = Path(text)
        if not text.strip() or not path.name:
            raise argparse.ArgumentTypeError(f"cannot write {text!r}: not a file name")
        if path.exists() and not path.is_file():
            kind = "a folder" if path.is_dir() else "not a regular file (a device or a pipe)"
            raise argparse.ArgumentTypeError(f"cannot write {text!r}: it is {kind}")
        if (path.exists() and not os.access(path, os.W_OK)) or not _can_create_in(path.parent):
            raise argparse.ArgumentTypeError(f"cannot write {text!r}")
        return path
    return convert


def writable_folder(text) -> Path:
    """Argument type: a folder that exists or can be made (not an existing file), and takes files."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"cannot write into {text!r}: it is a file, not a folder")
    if not _can_create_in(path):
        raise argparse.ArgumentTypeError(f"cannot write into {text!r}")
    return path


def _can_create_in(folder) -> bool:
    """Whether a new file can be created (and removed) in ``folder``, or, where it does not exist yet,
    in its nearest existing ancestor (which must be a folder)."""
    import tempfile
    probe = Path(folder)
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        return False
    try:
        with tempfile.TemporaryFile(dir=probe):
            return True
    except OSError:
        return False


def _readable_file(text) -> Path:
    """``Path(text)`` if it is an existing, readable file; else one-line ``ArgumentTypeError``."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"no such file {text!r}")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text!r} is not a file")
    if not os.access(path, os.R_OK):
        raise argparse.ArgumentTypeError(f"cannot read {text!r} (permission denied)")
    return path


def existing_file():
    """Argument type: a readable file (its content is checked by the command)."""
    return _readable_file


#: First bytes of a netCDF file: classic, 64-bit offset, CDF-5, and netCDF-4 (HDF5).
NETCDF_SIGNATURES = (b"CDF\x01", b"CDF\x02", b"CDF\x05", b"\x89HDF\r\n\x1a\n")


def dataset_file(*stages, check=None):
    """Argument type: a readable netCDF file of one of ``stages`` (any breastcore stage if none).

    Parameters
    ----------
    *stages : str
        Accepted values of the dataset's ``stage`` attribute (``mesh``, ``solve``,
        ``measure``, ``identify``, ...). None given: any netCDF file is accepted.
    check : callable, optional
        ``check(ds)`` on the opened dataset; a ``ValueError`` or ``KeyError`` it raises
        refuses the file with its message (e.g. a measurement that is not > 0).

    Returns
    -------
    callable
        ``text -> Path``, raising ``argparse.ArgumentTypeError`` with one line saying
        what is wrong: no such file, not readable, empty, not a netCDF file, damaged,
        no stage, or the stage it has and the stages expected.

    Notes
    -----
    Without it a wrong file fails deep in a command: xarray's message about IO backends
    for a file that is not netCDF, ``KeyError: No variable named 'posture'`` for a
    dataset of another stage. Only the attributes are read here (and what ``check``
    reads); the command opens the file again.
    """
    expected = " or ".join(repr(s) for s in stages)

    def convert(text):
        path = _readable_file(text)
        import xarray as xr
        try:
            ds = xr.open_dataset(path, engine="netcdf4")
        except Exception as err:            # netCDF4 and xarray raise OSError, ValueError, RuntimeError...
            with open(path, "rb") as f:
                head = f.read(8)
            if not head:
                raise argparse.ArgumentTypeError(f"{text!r} is empty (0 bytes), not a netCDF file") from None
            if not head.startswith(NETCDF_SIGNATURES):
                raise argparse.ArgumentTypeError(f"{text!r} is not a netCDF file") from None
            reason = getattr(err, "strerror", None) or (str(err).splitlines() or [type(err).__name__])[0]
            raise argparse.ArgumentTypeError(f"{text!r} cannot be read as netCDF ({reason}); "
                                             "damaged or truncated?") from None
        with ds:
            stage = ds.attrs.get("stage")
            if stages and stage is None:
                raise argparse.ArgumentTypeError(f"{text!r} has no 'stage' attribute: not a breastcore dataset "
                                                 f"(expected stage {expected})")
            if stages and stage not in stages:
                raise argparse.ArgumentTypeError(f"{text!r} is a dataset of stage {stage!r}, expected stage {expected}")
            if check is not None:
                try:
                    check(ds)
                except KeyError as err:         # xarray's message is a sentence listing the variables
                    named = re.search(r"named '([^']+)'", str(err))
                    missing = f"the variable {named.group(1)!r}" if named else str(err)
                    raise argparse.ArgumentTypeError(f"{text!r}: stage {stage!r} dataset without {missing}") from None
                except ValueError as err:
                    raise argparse.ArgumentTypeError(f"{text!r}: {err}") from None
        return path
    return convert


def check_measurements(ds) -> None:
    """``dataset_file`` check of a measurement dataset: every value usable (finite, > 0), and at
    least as many measurements of weight > 0 as identified parameters (``identify`` refuses fewer
    at run time, after the mesh is built; here it is one line while the command is parsed)."""
    from breastcore.inverse.identify import too_few_weighted
    from breastcore.io.targets import target_from_dataset
    from breastcore.model.parameters import IDENTIFIED
    refusal = too_few_weighted(target_from_dataset(ds).weights, len(IDENTIFIED))
    if refusal:
        raise ValueError(refusal)


def add_parameter_options(parser):
    """``--R --H --lambda-breast ...``: every model parameter, SI units, documented defaults and ranges."""
    group = parser.add_argument_group("model parameters (SI units; defaults: paper Λ̄ and spec §2)")
    for name, info in PARAMETER_INFO.items():
        kind = parameter_type(name)
        group.add_argument(info.cli, dest=name, type=kind, default=info.default, metavar=info.units.upper().replace(" ", ""),
                           help=f"{info.long_name} [{info.units}], {kind.range} (default {info.default:g}, {info.source})")


def parameters_from_args(args) -> Parameters:
    values = {name: getattr(args, name) for name in PARAMETER_INFO}
    try:
        return Parameters(**values)
    except ParameterError as err:
        name = str(err).split()[0]
        option = PARAMETER_INFO[name].cli if name in PARAMETER_INFO else name
        raise UsageError(f"{option}: {err}") from None


def postures_from_args(texts):
    try:
        postures = [parse_posture(t) for t in (texts or list(PAPER_POSTURES))]
    except PostureError as err:
        raise UsageError(f"--posture: {err}") from None
    names = [p.name for p in postures]
    if len(set(names)) != len(names):
        raise UsageError(f"--posture: repeated posture name in {names}")
    return postures


def add_mesh_options(parser, required=False):
    from breastcore.model.mesh import LEVEL_MESH_SIZE
    group = parser.add_mutually_exclusive_group(required=required)
    group.add_argument("--mesh", choices=list(LEVEL_MESH_SIZE), default=None if required else "coarse",
                       help="named mesh level (default coarse)")
    group.add_argument("--mesh-size", type=positive_float(), metavar="METRES",
                       help="gmsh characteristic length instead of a level, m, > 0")


def mesh_from_args(args, params=None):
    """The fixed-topology mesh of the level (at the paper's R, H; the map moves it)."""
    from breastcore.model.mesh import H0, R0, mesh_cap, mesh_level
    if getattr(args, "mesh_size", None):
        return mesh_cap(R0, H0, args.mesh_size), "custom", args.mesh_size
    from breastcore.model.mesh import LEVEL_MESH_SIZE
    return mesh_level(args.mesh), args.mesh, LEVEL_MESH_SIZE[args.mesh]
