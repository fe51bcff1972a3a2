"""Snakemake script of the mesh rule: calls breastcore.stages.mesh.run_mesh."""

from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.stages.mesh import run_mesh


def main(snakemake):
    spec = snakemake.params.spec
    key = spec_key(spec)
    with log_to(snakemake.log[0]):
        run_mesh(spec, snakemake.output[0], key)


if __name__ == "__main__":
    main(snakemake)  # noqa: F821 (injected by Snakemake)
