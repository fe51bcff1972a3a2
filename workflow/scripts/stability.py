"""Snakemake script of the stability rule: one chunk of grid cases, each a recorded outcome."""

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.stages.stability import run_stability


def main(snakemake):
    spec = snakemake.params.spec
    with log_to(snakemake.log[0]):
        run_stability(spec, snakemake.input.mesh, snakemake.output[0], spec_key(spec))


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
