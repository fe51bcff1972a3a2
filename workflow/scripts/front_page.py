"""Snakemake script of the report_front_page rule: the report's first page (HTML)."""

from breastcore.io.datasets import open_dataset, write_text
from breastcore.pipeline.logs import log_to
from breastcore.report.front_page import front_page


def main(snakemake):
    with log_to(snakemake.log[0]):
        scenes = [(name, open_dataset(summary), pictures) for name, summary, pictures in snakemake.params.scenes]
        write_text(front_page(scenes), snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
