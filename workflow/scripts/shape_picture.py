"""Snakemake script of the shape_picture rule: side and front views of one posture."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.plots import shape_figure


def main(snakemake):
    with log_to(snakemake.log[0]):
        shape_figure(open_dataset(snakemake.input[0]), snakemake.params.posture, snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
