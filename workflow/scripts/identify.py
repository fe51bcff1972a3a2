"""Snakemake script of the identify rule: calls breastcore.stages.identify.run_identify."""

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.stages.identify import run_identify


def main(snakemake):
    spec = snakemake.params.spec
    key = spec_key(spec)
    with log_to(snakemake.log[0]):
        run_identify(spec, snakemake.input.measurements, snakemake.input.mesh, snakemake.output[0], key)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
