"""Snakemake script of the report_front_page rule: the report's first page (HTML)."""

import os

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.front_page import front_page


def main(snakemake):
    out = snakemake.output[0]
    with log_to(snakemake.log[0]):
        page = front_page([(name, open_dataset(summary), pictures) for name, summary, pictures in snakemake.params.scenes])
        with open(out + ".part", "w", encoding="utf-8") as f:
            f.write(page)
        os.replace(out + ".part", out)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
