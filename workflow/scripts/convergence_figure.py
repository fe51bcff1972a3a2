"""Snakemake script of the convergence_figure rule: identification history."""

from breastcore.io.datasets import open_dataset
from breastcore.pipeline.logs import log_to
from breastcore.report.plots import convergence_figure


def main(snakemake):
    with log_to(snakemake.log[0]):
        runs = [open_dataset(p) for p in snakemake.input]
        labels = [f"{ds.attrs.get('mesh_level', '?')} · {ds.attrs.get('method', '?')}" for ds in runs]
        convergence_figure(runs, snakemake.output[0], labels)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
