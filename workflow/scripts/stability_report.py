"""Snakemake script of the stability_map / stability_table rules (PNG map, or CSV and HTML counts)."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.html_tables import write_table
from breastcore.report.plots import stability_map
from breastcore.report.summaries import stability_table


def main(snakemake):
    with log_to(snakemake.log[0]):
        ds = open_dataset(snakemake.input[0])
        if "csv" in snakemake.output.keys():
            write_table(stability_table(ds), snakemake.output.csv, snakemake.output.html,
                        "Stability: outcomes per grid cell")
        else:
            stability_map(ds, snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
