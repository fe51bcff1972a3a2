"""``breastcore identify``: Λ from a measurement dataset, with history and uncertainty."""

from __future__ import annotations

import sys

from breastcore.cli.options import (
    UsageError,
    add_mesh_options,
    add_parameter_options,
    check_measurements,
    dataset_file,
    fraction,
    mesh_from_args,
    non_negative_float,
    parameter_assignments,
    parameters_from_args,
    positive_float,
    positive_int,
    writable_path,
)
from breastcore.forward.options import SolverOptions
from breastcore.inverse.options import IdentificationOptions
from breastcore.model.parameters import IDENTIFIED, PARAMETER_INFO

#: The defaults of every option: the dataclasses' own (one source; README "Defaults").
OPTIONS, SOLVER = IdentificationOptions(), SolverOptions()


def parse_initial(text, defaults):
    """``R=0.05,H=0.04,mu_breast=120`` → the six values (others from ``defaults``), each > 0: a modulus
    may be 0 in a solve, never as a start of the identification, which scales each parameter by itself."""
    values, given = dict(zip(IDENTIFIED, defaults)), set()
    for item in filter(None, (t.strip() for t in (text or "").split(","))):
        key, _, value = item.partition("=")
        key = key.strip().replace("-", "_")
        if key not in values:
            raise UsageError(f"--initial: unknown parameter {key!r}; known: {', '.join(IDENTIFIED)}")
        try:
            values[key] = float(value)
        except ValueError:
            raise UsageError(f"--initial: {key}={value!r} is not a number") from None
        given.add(key)
    for name, value in values.items():
        if not value > 0:
            option = "--initial" if name in given else "--" + name.replace("_", "-")
            raise UsageError(f"{option}: the initial {name} = {value:g} {PARAMETER_INFO[name].units} must be > 0 "
                             "to be identified (both methods scale each parameter by itself: LM works in ln Λ, "
                             "Gauss–Newton in ΔΛ/Λ)")
    return [values[k] for k in IDENTIFIED]


def register(sub):
    p = sub.add_parser("identify", help="identify Λ = (R, H, λ, μ, λ_s, μ_s) from measurements",
                       description="Identify the six parameters from a measurement dataset; write the history, "
                                   "estimate, shapes, Jacobian, covariance and 95 % intervals.")
    p.add_argument("--measurements", required=True, type=dataset_file("measure", check=check_measurements),
                   metavar="M.nc", help="measurement dataset (stage measure, from breastcore measure)")
    add_mesh_options(p)
    p.add_argument("--initial", default="", metavar="R=..,H=..,...", type=parameter_assignments(IDENTIFIED),
                   help="initial guess of some of the six parameters (SI, each in the range of its option); "
                        "the rest from the parameter options")
    p.add_argument("--method", choices=["lm", "gauss-newton"], default=OPTIONS.method,
                   help="lm (Levenberg-Marquardt in log parameters, default) or gauss-newton (the paper's)")
    p.add_argument("--jacobian", choices=["implicit", "fd"], default=OPTIONS.jacobian,
                   help="implicit (adjoint-free sensitivities, default) or fd (forward differences)")
    p.add_argument("--solver", choices=["newton", "cg"], default=SOLVER.method,
                   help=f"forward solver (default {SOLVER.method})")
    # as solve's --rtol: RTOL >= 1 would accept the undeformed start
    p.add_argument("--rtol", type=fraction(zero=False), default=SOLVER.rtol,
                   help="forward solves stop when ‖free-dof gradient‖ ≤ RTOL × ‖gravity load‖, in (0, 1) "
                        f"(default {SOLVER.rtol:g}; recorded in the dataset's problem spec, reused by sensitivity)")
    # a step Λ_j(1 + ε) with ε >= 1 at least doubles Λ_j: no longer a derivative
    p.add_argument("--fd-step", type=fraction(zero=False), default=OPTIONS.fd_step,
                   help=f"relative FD step ε, in (0, 1) (default {OPTIONS.fd_step:g})")
    p.add_argument("--cost-tol", type=non_negative_float(), default=OPTIONS.cost_tol,
                   help=f"Gauss-Newton stop ε_m on the cost decrease, >= 0 (default {OPTIONS.cost_tol:g})")
    # a step never lowers the cost by more than all of it: cost_rtol >= 1 would stop after any step
    p.add_argument("--cost-rtol", type=fraction(), default=OPTIONS.cost_rtol,
                   help="both methods: stop, converged, after an accepted step that lowers the cost by less than "
                        f"this fraction of it, in [0, 1) (default {OPTIONS.cost_rtol:g}; 0: off)")
    p.add_argument("--max-iterations", type=positive_int(), default=OPTIONS.max_iterations,
                   help=f"iteration limit, integer >= 1 (default {OPTIONS.max_iterations})")
    p.add_argument("--noise", type=positive_float(), default=OPTIONS.noise,
                   help=f"relative 1σ measurement noise of the uncertainty model, > 0 (default {OPTIONS.noise:g})")
    p.add_argument("--initial-trust-radius", type=positive_float(), default=OPTIONS.initial_trust_radius,
                   help=f"LM: first trust-region radius in the log/logit parameters, > 0 "
                        f"(default {OPTIONS.initial_trust_radius:g})")
    p.add_argument("--fixed-iterations", action="store_true",
                   help="gauss-newton only: run exactly --max-iterations iterations without the ε_m test "
                        "(the paper's evolution runs); never reported converged")
    p.add_argument("--warm-radius", type=non_negative_float(), default=OPTIONS.warm_radius,
                   help="warm-start a forward solve only from equilibria within this relative distance of the new "
                        f"Λ (max over the six), >= 0; 0: always cold between different Λ (default {OPTIONS.warm_radius:g})")
    p.add_argument("--processes", type=positive_int(), default=1,
                   help="solve the postures in this many processes, integer >= 1 "
                        "(default 1; 2 pays from the thin mesh up)")
    add_parameter_options(p)
    p.add_argument("--out", required=True, type=writable_path(), metavar="ID.nc")
    p.set_defaults(run=run)


def run(args):
    from breastcore.forward.options import SolverOptions
    from breastcore.inverse.options import IdentificationOptions
    from breastcore.inverse.uncertainty import SEEN, limit_note
    from breastcore.io.datasets import open_dataset, write_netcdf
    from breastcore.io.targets import target_from_dataset, truth_from_dataset
    from breastcore.problem import ProblemSpec
    from breastcore.stages.identify import identify_target

    base = parameters_from_args(args)
    initial = parse_initial(args.initial, base.identified())
    try:
        base = base.with_identified(initial)
    except ValueError as err:
        raise UsageError(f"--initial: {err}") from None
    try:
        options = IdentificationOptions(method=args.method, jacobian=args.jacobian, fd_step=args.fd_step,
                                        cost_tol=args.cost_tol, cost_rtol=args.cost_rtol,
                                        max_iterations=args.max_iterations, noise=args.noise,
                                        initial_trust_radius=args.initial_trust_radius,
                                        fixed_iterations=args.fixed_iterations, warm_radius=args.warm_radius)
    except ValueError as err:
        raise UsageError(f"identification options: {err}") from None
    ds_m = open_dataset(args.measurements)
    target = target_from_dataset(ds_m)
    for note in target.notes:                  # what the input checks let through: implausible or unusual values
        print(f"breastcore identify: warning: {note}", file=sys.stderr)
    mesh, level, _ = mesh_from_args(args)
    problem = ProblemSpec(parameters=base, solver=SolverOptions(method=args.solver, rtol=args.rtol),
                          postures=target.postures,
                          measurement_set=target.measurement_set, identification=options)
    ds = identify_target(problem, mesh, target, truth_from_dataset(ds_m), initial, mesh_level=level,
                         processes=args.processes)
    write_netcdf(ds, args.out)
    for name, value, lo, hi, ok, decades, limit in zip(IDENTIFIED, ds["estimate"].values, ds["interval_low"].values,
                                                       ds["interval_high"].values, ds["determined"].values,
                                                       ds["interval_decades"].values, ds["limit"].values):
        unit = PARAMETER_INFO[name].units
        interval = (limit_note(int(limit), value, unit) if limit != SEEN else
                    f"95 %: {lo:.4g} … {hi:.4g}" if ok else
                    f"not determined by these measurements: its 95 % interval spans {decades:.3g} decades")
        print(f"{name:>14s} = {value:.6g} {unit}  ({interval})")
    print(f"{'cost':>14s} = {ds['cost'].values[-1]:.3e} after {ds.sizes['iteration'] - 1} iterations; "
          f"{ds.attrs['message']}")
    print(f"{'fit verdict':>14s} = {ds.attrs['verdict']}: {ds.attrs['verdict_message']}")
    if ds.attrs["regime_warning"]:
        print(f"breastcore identify: warning: {ds.attrs['regime_warning']}", file=sys.stderr)
    print(f"wrote {args.out}")
    if ds.attrs["verdict"] != "consistent":    # written, but not an estimate to use as it is
        print(f"breastcore identify: {ds.attrs['verdict_message']} (history saved)", file=sys.stderr)
        return 1
    return 0
