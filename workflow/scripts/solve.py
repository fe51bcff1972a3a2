"""Snakemake script of the solve rule: calls breastcore.pipeline.run_solve."""

from breastcore.logs import log_to
from breastcore.pipeline import run_solve
from breastcore.workflow_plan import spec_key


def main(snakemake):
    spec = snakemake.params.spec
    key = spec_key(spec)
    with log_to(snakemake.log[0]):
        run_solve(spec, snakemake.input.mesh, snakemake.output[0], key)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
