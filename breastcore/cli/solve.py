"""``breastcore solve``: equilibrium shapes per posture, written as a solution dataset."""

from __future__ import annotations

import sys

from breastcore.cli.options import (
    add_mesh_options,
    add_parameter_options,
    fraction,
    mesh_from_args,
    parameters_from_args,
    posture_text,
    postures_from_args,
    writable_path,
)
from breastcore.forward.options import SolverOptions


def register(sub):
    p = sub.add_parser("solve", help="solve the forward model in each posture",
                       description="Solve the equilibrium of the breast under gravity in each posture and "
                                   "write the solution dataset (netCDF).")
    add_mesh_options(p)
    p.add_argument("--posture", action="append", metavar="NAME[=ANGLE]", type=posture_text,
                   help="posture, repeatable: standing (0°), bent45 (45°), fours (90°) or NAME=ANGLE in "
                        "degrees within [0, 90] (default: the paper's three)")
    add_parameter_options(p)
    defaults = SolverOptions()
    p.add_argument("--solver", choices=["newton", "cg"], default=defaults.method,
                   help=f"newton (exact Hessian) or cg (the paper's baseline) (default {defaults.method})")
    # RTOL >= 1 would accept the undeformed start, whose gradient is the gravity load itself
    p.add_argument("--rtol", type=fraction(zero=False), default=defaults.rtol,
                   help=f"stop when ‖free-dof gradient‖ ≤ RTOL × ‖gravity load‖, in (0, 1) (default {defaults.rtol:g})")
    p.add_argument("--out", required=True, type=writable_path(), metavar="FILE.nc",
                   help="output solution dataset")
    p.set_defaults(run=run)


def run(args):
    from breastcore.forward.options import SolverOptions
    from breastcore.io.datasets import write_netcdf
    from breastcore.io.solution import solution_dataset, solve_postures
    from breastcore.problem import ProblemSpec

    problem = ProblemSpec(parameters=parameters_from_args(args), solver=SolverOptions(method=args.solver, rtol=args.rtol),
                          postures=tuple(postures_from_args(args.posture)))
    params = problem.parameters
    mesh, level, _ = mesh_from_args(args)
    model = problem.forward_model(mesh)
    solutions = solve_postures(model, params, problem.postures)
    shown = model.mesh_at(params)
    ds = solution_dataset(shown, problem, solutions, mesh_level=level)
    write_netcdf(ds, args.out)
    for s in solutions:
        print(f"{s.posture.name:>10s}: {s.iterations:3d} iterations, |g| = {s.gradient_norm:.2e} N "
              f"(tol {s.tolerance:.2e}), {s.wall_time:.2f} s")
    print(f"wrote {args.out}")
    if ds.attrs["regime_warning"]:
        print(f"breastcore solve: warning: {ds.attrs['regime_warning']}", file=sys.stderr)
    if any(s.negative_eigenvalues > 0 for s in solutions):     # written, but not a shape to use as it is
        print("breastcore solve: a posture ended on a saddle, not a stable equilibrium (dataset written)",
              file=sys.stderr)
        return 1
