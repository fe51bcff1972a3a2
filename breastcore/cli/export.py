"""``breastcore export``: one mesh file per posture for ParaView, through meshio."""

from __future__ import annotations

from breastcore.cli.options import dataset_file, writable_folder


def register(sub):
    p = sub.add_parser("export", help="write VTU/XDMF files of a solution for ParaView",
                       description="Write one mesh file per posture (deformed tets with the displacement "
                                   "field, in metres) next to the output prefix.")
    # an identification carries the shapes at its estimate too (the workflow exports those)
    p.add_argument("solution", type=dataset_file("solve", "identify"), metavar="SOLUTION.nc",
                   help="solution or identification dataset (stage solve or identify)")
    p.add_argument("--format", choices=["vtu", "xdmf"], default="vtu", help="file format (default vtu)")
    p.add_argument("--out-dir", default=None, type=writable_folder,
                   help="folder for the files (default: beside SOLUTION.nc)")
    p.set_defaults(run=run)


def run(args):
    from breastcore.io.datasets import open_dataset
    from breastcore.io.export import export_solution

    ds = open_dataset(args.solution)
    folder = args.out_dir or args.solution.parent
    for path in export_solution(ds, folder, args.solution.stem, args.format):
        print(f"wrote {path}")
