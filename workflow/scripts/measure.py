"""Snakemake script of the measure rule: calls breastcore.stages.measure.run_measure."""

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.stages.measure import run_measure


def main(snakemake):
    spec = snakemake.params.spec
    key = spec_key(spec)
    with log_to(snakemake.log[0]):
        run_measure(spec, snakemake.input.solution or None, snakemake.output[0], key)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
