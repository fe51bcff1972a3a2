"""Snakemake script of the scene_summary rule: one summary dataset per scene."""

from breastcore.io.datasets import write_netcdf
from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.logs import log_to
from breastcore.report.calibration import calibration_summary
from breastcore.report.summaries import record_datasets, solution_summary, stability_summary, synthetic_summary


def main(snakemake):
    spec, name = snakemake.params.spec, snakemake.params.scene
    with log_to(snakemake.log[0]):
        if spec["kind"] == "stability":
            ds = stability_summary(spec["chunks"], name, spec_key(spec), guesses=spec.get("guesses", []))
        elif spec["kind"] == "calibration":
            ds = calibration_summary(spec, name, spec_key(spec))
        elif spec["kind"] == "synthetic":
            ds = synthetic_summary(spec["runs"], [r["identification"] for r in spec["runs"]], name, spec_key(spec),
                                   tables=spec.get("tables", []), sensitivity=spec.get("sensitivity", []),
                                   paper_table=spec.get("paper_table", "none"), truth=spec["truth"],
                                   level_solutions=spec.get("level_solutions"),
                                   truth_mesh=spec["truth_mesh"])
        else:
            source = spec["identification"] if spec["kind"] == "patient" else spec["solution"]
            ds = solution_summary(source, name, spec["kind"], spec_key(spec))
        write_netcdf(record_datasets(ds, snakemake.params.datasets), snakemake.output[0])


if __name__ == "__main__":
    main(snakemake)  # noqa: F821
