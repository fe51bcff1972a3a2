"""Snakemake script of the diagnostics_table rule: solver diagnostics per posture (CSV, and HTML for the report)."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.html_tables import write_table
from breastcore.report.summaries import diagnostics_table


def main(snakemake):
    with log_to(snakemake.log[0]):
        write_table(diagnostics_table(open_dataset(snakemake.input[0])), snakemake.output.csv, snakemake.output.html,
                    "Forward-solver diagnostics per posture", index=True)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
