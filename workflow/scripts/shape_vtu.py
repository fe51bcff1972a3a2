"""Snakemake script of the shape_vtu rule: the deformed mesh of one posture for ParaView."""

from pathlib import Path

from breastcore.io.datasets import open_dataset
from breastcore.io.export import export_solution
from breastcore.pipeline.logs import log_to


def main(snakemake):
    out = Path(snakemake.output[0])
    with log_to(snakemake.log[0]):
        ds = open_dataset(snakemake.input[0]).sel(posture=[snakemake.params.posture])
        written = export_solution(ds, out.parent, "shape", "vtu")
        assert written == [out], written


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
