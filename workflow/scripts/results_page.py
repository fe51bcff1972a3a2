"""Snakemake script of the results_page rule: docs/results.md from the scene summaries."""

from breastcore.pipeline.logs import log_to
from breastcore.report.results_page import render


def main(snakemake):
    with log_to(snakemake.log[0]):
        page = render(dict(snakemake.input.items()), snakemake.params.commands)
        with open(snakemake.output[0], "w") as f:
            f.write(page + "\n")


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
