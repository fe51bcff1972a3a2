"""Snakemake script of the sensitivity_figure rule: the sensitivity heatmap."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.plots import sensitivity_figure


def main(snakemake):
    with log_to(snakemake.log[0]):
        sensitivity_figure(open_dataset(snakemake.input[0]), snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
