"""Snakemake script of the calibration_figure rule: the Table-2 residual per level, one line per c."""

from breastcore.calibration_scene import residual_figure
from breastcore.datasets import open_dataset
from breastcore.logs import log_to


def main(snakemake):
    with log_to(snakemake.log[0]):
        residual_figure(open_dataset(snakemake.input[0]), snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
