"""Snakemake script of the measure rule: calls breastcore.pipeline.run_measure."""

from breastcore.logs import log_to
from breastcore.pipeline import run_measure
from breastcore.workflow_plan import spec_key


def main(snakemake):
    spec = snakemake.params.spec
    key = spec_key(spec)
    with log_to(snakemake.log[0]):
        run_measure(spec, snakemake.input.solution or None, snakemake.output[0], key)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
