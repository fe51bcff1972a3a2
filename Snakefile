# breastcore: scenes of config.yaml -> cached netCDF stages -> report. See README.md.
import os

from snakemake.utils import min_version

from breastcore.pipeline.config import validate_config
from breastcore.pipeline.config_files import check_config_files
from breastcore.pipeline.overlays import check_overlays, config_errors_exit, drop_keys

min_version("9.0")  # --replace-workflow-config (below, and in the advice of a refused copy)

# Every config error is one line, "ConfigError: config ...", and exit status 1: without
# config_errors_exit Snakemake would print the Snakefile line and the frames that raised it.
# config.yaml is read here first because Snakemake's loader, on a syntax error, names
# neither the file nor the line.
with config_errors_exit():
    check_config_files(["config.yaml"] if os.path.exists("config.yaml") else [])

configfile: "config.yaml"

with config_errors_exit():
    check_config_files(workflow.configfiles)
    # A --configfile copy that leaves out a key, a scene or a section of config.yaml would run
    # config.yaml's. (--replace-workflow-config, which runs the files alone, came with
    # Snakemake 9.0.0, snakemake/snakemake#3381; Snakemake 8 always merges)
    SCHEMA = os.path.join(workflow.basedir, "workflow/schemas/config.schema.yaml")
    drop_keys(config, check_overlays("config.yaml", workflow.config_settings.configfiles,
                                     workflow.config_settings.replace_workflow_config, SCHEMA))
    config.update(validate_config(config, SCHEMA))

include: "workflow/rules/common.smk"
include: "workflow/rules/mesh.smk"
include: "workflow/rules/solve.smk"
include: "workflow/rules/measure.smk"
include: "workflow/rules/identify.smk"
include: "workflow/rules/sensitivity.smk"
include: "workflow/rules/studies.smk"
include: "workflow/rules/calibration.smk"
include: "workflow/rules/report.smk"

# The report opens on each scene's findings (results/report/front.html, rule report_front_page);
# before a run has written that page, on a note that says so: docutils fails on a missing file.
report: "workflow/report/workflow.rst" if os.path.exists(f"{RESULTS}/report/front.html") else "workflow/report/no_findings.rst"


rule all:
    input: PLAN.all_targets()
    default_target: True
