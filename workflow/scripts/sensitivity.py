"""Snakemake script of the sensitivity rule: calls breastcore.stages.sensitivity.run_sensitivity."""

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.stages.sensitivity import run_sensitivity


def main(snakemake):
    spec = snakemake.params.spec
    key = spec_key(spec)
    with log_to(snakemake.log[0]):
        run_sensitivity(spec, snakemake.input.identification, snakemake.output[0], key, snakemake.threads)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
