"""Snakemake script of the parameter_table rule: estimate and 95 % intervals (CSV)."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.summaries import parameter_table


def main(snakemake):
    with log_to(snakemake.log[0]):
        parameter_table(open_dataset(snakemake.input[0])).to_csv(snakemake.output[0], index=False)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
