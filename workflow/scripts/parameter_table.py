"""Snakemake script of the parameter_table rule: estimate and 95 % intervals (CSV, and HTML for the report)."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.html_tables import write_table
from breastcore.report.summaries import parameter_table


def main(snakemake):
    with log_to(snakemake.log[0]):
        write_table(parameter_table(open_dataset(snakemake.input[0])), snakemake.output.csv, snakemake.output.html,
                    "Identified parameters: estimate and 95 % interval")


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
