"""``breastcore sensitivity``: the 6×15 sensitivity matrix, finite (paper) and linearised."""

from __future__ import annotations

from breastcore.cli.options import dataset_file, fraction, positive_int, writable_path


def register(sub):
    p = sub.add_parser("sensitivity", help="sensitivity of Λ to each measurement",
                       description="Relative sensitivity ∂lnΛ/∂ln m: the paper's re-identification with each "
                                   "m_i × (1 ± δ), and the linearised (JᵀJ)⁻¹Jᵀ from the same Jacobian.")
    p.add_argument("identification", type=dataset_file("identify"), metavar="ID.nc",
                   help="identification dataset (stage identify, from breastcore identify)")
    # m_i (1 - δ) must stay > 0, and δ = 0 would divide by zero
    p.add_argument("--delta", type=fraction(zero=False), default=0.10,
                   help="relative perturbation δ of each measurement, in (0, 1) (default 0.10)")
    p.add_argument("--linearised-only", action="store_true", help="skip the 2n re-identifications")
    p.add_argument("--processes", type=positive_int(), default=1,
                   help="forked processes for the 2n re-identifications, integer >= 1 "
                        "(default 1; same results for any value)")
    p.add_argument("--out", required=True, type=writable_path(), metavar="S.nc")
    p.set_defaults(run=run)


def run(args):
    from breastcore.stages.sensitivity import run_sensitivity

    run_sensitivity({"finite": not args.linearised_only, "delta": args.delta}, args.identification, args.out,
                    processes=args.processes)
    print(f"wrote {args.out}")
