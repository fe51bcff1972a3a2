"""Snakemake script of the diagnostics_table rule: solver diagnostics per posture (CSV)."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.summaries import diagnostics_table


def main(snakemake):
    with log_to(snakemake.log[0]):
        diagnostics_table(open_dataset(snakemake.input[0])).to_csv(snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
