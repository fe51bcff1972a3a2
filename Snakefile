# breastcore: scenes of config.yaml -> cached netCDF stages -> report. See README.md.
import os

from snakemake.utils import min_version

from breastcore.workflow_config import check_config_files, validate_config

min_version("8.0")

configfile: "config.yaml"

check_config_files(workflow.configfiles)
config.update(validate_config(config, os.path.join(workflow.basedir, "workflow/schemas/config.schema.yaml")))

include: "workflow/rules/common.smk"
include: "workflow/rules/mesh.smk"
include: "workflow/rules/solve.smk"
include: "workflow/rules/measure.smk"
include: "workflow/rules/identify.smk"
include: "workflow/rules/sensitivity.smk"
include: "workflow/rules/studies.smk"
include: "workflow/rules/report.smk"


rule all:
    input: PLAN.all_targets()
    default_target: True
