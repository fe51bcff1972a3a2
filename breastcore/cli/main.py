"""Command line: ``breastcore solve | export | measure | identify | sensitivity | show | list | compare``.

Bad input gives a one-line ``breastcore: error: ...`` naming the option and the offending
value, exit status 2 and no traceback; a solve that fails gives its diagnostics and status 1.
Numbers and dataset files are checked by the argparse types of this module while the command
line is parsed, before any work: :class:`Bounded` (with :func:`positive_float`,
:func:`non_negative_float`, :func:`fraction`, :func:`positive_int`, :func:`parameter_type`)
and :func:`dataset_file`.
"""

from __future__ import annotations

import logging
import os
import sys

from breastcore.cli import browse, compare, export, identify, measure, sensitivity, solve
from breastcore.cli.options import UsageError, _Parser

#: Each entry registers one sub-command on an argparse sub-parser collection.
REGISTRY = [solve.register, export.register, measure.register, identify.register, sensitivity.register, browse.register,
            compare.register]


def build_parser():
    parser = _Parser(prog="breastcore", description=__doc__.splitlines()[0])
    parser.add_argument("-v", "--verbose", action="store_true", help="log every Newton / identification iteration")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for register in REGISTRY:
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
    except BrokenPipeError:   # `breastcore show x.nc | head`: the reader left, as it may from any filter
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())   # no second error at exit
        return 141
    except Exception as err:  # a failed solve or identification: one line, diagnostics included
        if args.verbose:
            raise
        from breastcore.forward.records import SolveError
        kind = "solve failed" if isinstance(err, SolveError) else type(err).__name__
        print(f"breastcore {args.command}: {kind}: {err}", file=sys.stderr)
        return 1
