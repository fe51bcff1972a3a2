"""Snakemake script of the uniqueness rule: calls breastcore.stages.uniqueness.run_uniqueness."""

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.stages.uniqueness import run_uniqueness


def main(snakemake):
    spec = snakemake.params.spec
    with log_to(snakemake.log[0]):
        run_uniqueness(spec, snakemake.input.mesh, snakemake.output[0], spec_key(spec))


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
