"""Command line: ``breastcore solve | export | measure | identify | sensitivity | show | list``.

Bad input gives a one-line ``breastcore: error: ...`` naming the option, exit
status 2 and no traceback; a solve that fails gives its diagnostics and status 1.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from pathlib import Path

from .parameters import PARAMETER_INFO, ParameterError, Parameters
from .postures import PAPER_POSTURES, PostureError, parse_posture


class UsageError(Exception):
    """Bad command-line input: printed as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(message)


def _positive_float(option):
    def convert(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option}: {text!r} is not a number") from None
        if not value > 0 or value != value or value == float("inf"):
            raise argparse.ArgumentTypeError(f"{option}: must be a positive finite number, got {text}")
        return value
    return convert


def writable_path(option):
    """Argument type: a file path whose folder exists (or can be made) and is writable."""
    def convert(text):
        path = Path(text)
        folder = path.parent if str(path.parent) else Path(".")
        probe = folder
        while not probe.exists():
            probe = probe.parent
        if not probe.is_dir() or not os.access(probe, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
            raise argparse.ArgumentTypeError(f"{option}: cannot write {text!r}")
        return path
    return convert


def existing_file(option):
    def convert(text):
        if not Path(text).is_file():
            raise argparse.ArgumentTypeError(f"{option}: no such file {text!r}")
        return Path(text)
    return convert


def add_parameter_options(parser):
    """``--R --H --lambda-breast ...``: every model parameter, SI units, documented defaults."""
    group = parser.add_argument_group("model parameters (SI units; defaults: paper Λ̄ and spec §2)")
    for name, info in PARAMETER_INFO.items():
        group.add_argument(info.cli, dest=name, type=float, default=info.default, metavar=info.units.upper().replace(" ", ""),
                           help=f"{info.long_name} [{info.units}] (default {info.default:g}, {info.source})")


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
    from .mesh import LEVEL_MESH_SIZE
    group = parser.add_mutually_exclusive_group(required=required)
    group.add_argument("--mesh", choices=list(LEVEL_MESH_SIZE), default=None if required else "coarse",
                       help="named mesh level (default coarse)")
    group.add_argument("--mesh-size", type=_positive_float("--mesh-size"), metavar="METRES",
                       help="gmsh characteristic length instead of a level, m")


def mesh_from_args(args, params=None):
    """The fixed-topology mesh of the level (at the paper's R, H; the map moves it)."""
    from .mesh import R0, H0, mesh_cap, mesh_level
    if getattr(args, "mesh_size", None):
        return mesh_cap(R0, H0, args.mesh_size), "custom", args.mesh_size
    from .mesh import LEVEL_MESH_SIZE
    return mesh_level(args.mesh), args.mesh, LEVEL_MESH_SIZE[args.mesh]


def build_parser():
    parser = _Parser(prog="breastcore", description=__doc__.splitlines()[0])
    parser.add_argument("-v", "--verbose", action="store_true", help="log every Newton / identification iteration")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    from . import commands
    for register in commands.REGISTRY:
        register(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except UsageError as err:
        print(f"breastcore: error: {err}", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(name)s %(message)s", stream=sys.stderr)
    try:
        return int(args.run(args) or 0)
    except UsageError as err:
        print(f"breastcore {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except Exception as err:  # a failed solve or identification: one line, diagnostics included
        if args.verbose:
            raise
        from .forward import SolveError
        kind = "solve failed" if isinstance(err, SolveError) else type(err).__name__
        print(f"breastcore {args.command}: {kind}: {err}", file=sys.stderr)
        return 1
