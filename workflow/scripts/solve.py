"""Snakemake script of the solve rule: calls breastcore.stages.solve.run_solve."""

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.stages.solve import run_solve


def main(snakemake):
    spec = snakemake.params.spec
    key = spec_key(spec)
    with log_to(snakemake.log[0]):
        run_solve(spec, snakemake.input.mesh, snakemake.output[0], key)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
