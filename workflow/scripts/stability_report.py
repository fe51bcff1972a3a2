"""Snakemake script of the stability_map / stability_table rules (PNG map or CSV counts)."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.plots import stability_map
from breastcore.report.summaries import stability_table


def main(snakemake):
    out = snakemake.output[0]
    with log_to(snakemake.log[0]):
        ds = open_dataset(snakemake.input[0])
        if out.endswith(".png"):
            stability_map(ds, out)
        else:
            stability_table(ds).to_csv(out, index=False)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
