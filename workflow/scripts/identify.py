"""Snakemake script of the identify rules: calls breastcore.stages.identify.run_identifications."""

from breastcore.stages.identify import run_identifications


def main(snakemake):
    # one output (rule identify) or a batch (rules identify_batch_<key>): one spec and log each
    run_identifications(snakemake.params.specs, snakemake.input.measurements, snakemake.input.mesh,
                        list(snakemake.output), list(snakemake.log), snakemake.rule)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
