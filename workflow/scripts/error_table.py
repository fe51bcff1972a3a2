"""Snakemake script of the error_table rule: mean parameter error per mesh and offset (CSV, %)."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.summaries import error_table_with_units


def main(snakemake):
    with log_to(snakemake.log[0]):
        error_table_with_units(open_dataset(snakemake.input[0])).to_csv(snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
