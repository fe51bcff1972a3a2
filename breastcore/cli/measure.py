"""``breastcore measure``: the 5 measurements per posture, from a solution or a patient file."""

from __future__ import annotations

import sys
import warnings

from breastcore.cli.options import UsageError, dataset_file, existing_file, writable_path


def register(sub):
    p = sub.add_parser("measure", help="measure a solution (or convert a patient file) into a measurement dataset",
                       description="Write measurement(posture, quantity) in SI units (m3, m2, m). Give either a "
                                   "solution dataset or --patient FILE (YAML or CSV in mm, cm2, ml).")
    p.add_argument("solution", nargs="?", type=dataset_file("solve"), metavar="SOLUTION.nc",
                   help="solution dataset (stage solve, from breastcore solve)")
    p.add_argument("--patient", type=existing_file(), metavar="FILE",
                   help="patient measurements (.yaml/.yml/.csv) in clinical units")
    p.add_argument("--allow-implausible", action="store_true",
                   help="with --patient: keep values that no shape of the model produces (back_depth > "
                        "frontal_depth, area < π back_depth², volume < (2π/3) back_depth³), flagged in every "
                        "output, instead of refusing them")
    p.add_argument("--set", dest="measurement_set", choices=["paper15", "exact"], default=None,
                   help="paper15 (tape and ruler formulas, default) or exact (mesh volume and skin area)")
    p.add_argument("--out", required=True, type=writable_path(), metavar="M.nc")
    p.set_defaults(run=run)


def run(args):
    from breastcore.inverse.measurements import MeasurementError
    from breastcore.io.datasets import open_dataset, write_netcdf
    from breastcore.io.patient import ImplausibleMeasurements, MeasurementWarning, load_patient
    from breastcore.io.targets import measure_solution, measurement_dataset

    if (args.solution is None) == (args.patient is None):
        raise UsageError("give exactly one of SOLUTION.nc or --patient FILE")
    if args.patient is not None:
        try:
            with warnings.catch_warnings():     # Python's own line, with a source line: the notes say it below
                warnings.simplefilter("ignore", MeasurementWarning)
                target = load_patient(args.patient, args.measurement_set, args.allow_implausible)
        except ImplausibleMeasurements as err:  # its advice names the option that runs the values
            raise UsageError(f"--patient: {err.advice('--allow-implausible')}") from None
        except MeasurementError as err:
            raise UsageError(f"--patient: {err}") from None
        ds = measurement_dataset(target, "patient")
        for note in target.notes:
            print(f"breastcore measure: warning: {note}", file=sys.stderr)
    else:
        from breastcore.problem import ProblemSpec
        solution = open_dataset(args.solution)
        try:
            target, marks = measure_solution(solution, args.measurement_set or "paper15")
        except MeasurementError as err:     # e.g. non-finite positions, or a shape measured <= 0
            raise UsageError(f"SOLUTION.nc {str(args.solution)!r}: {err}") from None
        problem = ProblemSpec.from_dataset(solution).replace(measurement_set=target.measurement_set)
        ds = measurement_dataset(target, str(args.solution), landmarks=marks, problem=problem)
    write_netcdf(ds, args.out)
    from breastcore.report.clinical import QUANTITY_UNITS
    table = ds["measurement"].transpose("posture", "quantity").to_pandas()
    for q in table.columns:                     # echoed as a tape reads: ml, cm², mm (the dataset stays SI)
        table[q] = table[q] * QUANTITY_UNITS[str(q)][1]
    table.columns = [f"{q} [{QUANTITY_UNITS[str(q)][0]}]" for q in table.columns]
    print(table.to_string(float_format=lambda v: f"{v:.4g}"))
    print(f"wrote {args.out}")

