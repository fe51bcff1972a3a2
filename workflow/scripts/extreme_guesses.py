"""Snakemake script of the extreme_guesses rule: identification from ×0.25 and ×4 moduli."""

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.stages.extreme import run_extreme_guesses


def main(snakemake):
    spec = snakemake.params.spec
    with log_to(snakemake.log[0]):
        run_extreme_guesses(spec, snakemake.input.mesh, snakemake.output[0], spec_key(spec))


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
