"""Snakemake script of the error_table rule: mean parameter error per mesh and offset (CSV, %, and HTML for the report)."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.html_tables import write_table
from breastcore.report.summaries import error_table_with_units


def main(snakemake):
    with log_to(snakemake.log[0]):
        write_table(error_table_with_units(open_dataset(snakemake.input[0])), snakemake.output.csv,
                    snakemake.output.html, "Mean parameter error per mesh and offset", index=True)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
