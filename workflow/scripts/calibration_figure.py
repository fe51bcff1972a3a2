"""Snakemake script of the calibration_figure rule: the Table-2 residual per level, one line per c."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.calibration_page import residual_figure


def main(snakemake):
    with log_to(snakemake.log[0]):
        residual_figure(open_dataset(snakemake.input[0]), snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
