"""``breastcore compare A B``: are two results folders identical, dataset by dataset, wall times aside?"""

from __future__ import annotations

import argparse
from pathlib import Path

from breastcore.cli.options import UsageError

DESCRIPTION = ("Compare two workflow results folders (results/ of two runs of one config, e.g. before and after "
               "a refactoring) dataset by dataset: the .nc files are paired by scene name, by the result paths "
               "the datasets name and by relative name, then every variable, coordinate and attribute must be "
               "exactly equal, wall times and provenance (created, source_hash, config_hash, breastcore_version) "
               "aside. Prints a report. Exit status 0 when every dataset is identical, 1 when not, 2 on bad input.")


def results_folder(text) -> Path:
    """argparse type: a folder holding ``.nc`` datasets (anything else is refused in one line)."""
    from breastcore.report.compare import ResultsFolder, ResultsFolderError
    try:
        ResultsFolder(text)
    except ResultsFolderError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    return Path(text)


def add_arguments(parser):
    """Add ``A B [--allow-unpaired]`` to ``parser``."""
    parser.add_argument("folder_a", type=results_folder, metavar="A", help="results folder of one run (e.g. before)")
    parser.add_argument("folder_b", type=results_folder, metavar="B", help="results folder of the other run (after)")
    parser.add_argument("--allow-unpaired", action="store_true",
                        help="datasets found in one folder only are listed but do not make the folders differ")


def register(sub):
    """Add the ``compare`` sub-command to the argparse sub-parser collection ``sub``."""
    p = sub.add_parser("compare", help="compare two results folders dataset by dataset "
                                       "(exit status 0: identical, 1: not)", description=DESCRIPTION)
    add_arguments(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Print the report; return 0 when every dataset is identical, 1 when not."""
    from breastcore.report.compare import ResultsFolderError, compare_results, render
    try:
        result = compare_results(args.folder_a, args.folder_b, allow_unpaired=args.allow_unpaired)
    except ResultsFolderError as err:       # e.g. a folder emptied since the command line was parsed
        raise UsageError(str(err)) from None
    print(render(result))
    return 0 if result.identical else 1
