"""Snakemake script of the calibrate rule: calls breastcore.stages.calibrate.run_calibrate."""

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.stages.calibrate import run_calibrate


def main(snakemake):
    spec = snakemake.params.spec
    with log_to(snakemake.log[0]):
        run_calibrate(spec, snakemake.input.mesh, snakemake.output[0], spec_key(spec))


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
