"""Snakemake script of the convergence_figure rule: identification history."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.plots import convergence_figure


def main(snakemake):
    with log_to(snakemake.log[0]):
        convergence_figure([open_dataset(p) for p in snakemake.input], snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
