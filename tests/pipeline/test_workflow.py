"""The Snakemake workflow end to end on a tiny config, then dry runs for the caching rules."""

import copy
import json
import os
import re
import shutil
import stat
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
import xarray as xr
import yaml

from breastcore.model.parameters import Parameters

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")

TINY = {
    "report": {"enabled": True},
    "scenes": {
        "syn": {"kind": "synthetic", "truth_mesh": "medium", "meshes": ["coarse"], "offsets": [0.1], "paper_table": "table1",
                # sensitivity both: its 30 re-identifications are the fixture's longest job, so
                # their iterations are capped at 6 (it records how many hit the cap)
                "sensitivity": "both", "tables": ["levels"], "identification": {"max_iterations": 6},
                "methods": [{"name": "lm", "max_iterations": 6},
                            {"name": "paper", "method": "gauss-newton", "jacobian": "fd", "max_iterations": 2}]},
        "grid": {"kind": "stability", "meshes": ["coarse"], "sample": 3, "chunks": 1,
                 "grid": {"mu": [15.0, 1500.0], "delta": [1e-7], "posture": ["standing", "fours"]},
                 "extreme_guesses": [4.0], "identification": {"max_iterations": 8}},
        "alice": {"kind": "patient", "mesh": "coarse", "identification": {"max_iterations": 15},
                  "sensitivity": "linearised",
                  "postures": {"standing": {"volume": 660, "area": 344, "height": 110, "frontal_depth": 51,
                                            "back_depth": 45},
                               "bent45": {"volume": 1230, "area": 296, "height": 89, "frontal_depth": 68,
                                          "back_depth": 67},
                               "fours": {"volume": 1014, "area": 238, "height": 105, "frontal_depth": 68,
                                         "back_depth": 68}}},
        "fwd": {"kind": "forward", "mesh": "coarse", "postures": ["standing"]},
        # Two values of c, coarse against medium, the truth and one admissible corner (H×1.3
        # is no cap: recorded, not solved); at the default c its truth solve and measurements are syn's.
        "cal": {"kind": "calibration", "grid": [1000.0, 500.0], "levels": ["coarse"], "reference": "medium",
                "compare_level": "coarse", "jacobian_level": "coarse", "probe_level": "coarse",
                "box_parameters": ["H"], "box_factors": [0.9, 1.3], "identify_meshes": ["coarse"], "starts": 1, "seed": 0,
                "truth_mesh": "medium", "identification": {"max_iterations": 2}},
    },
}


def snakemake(workdir, *args):
    return subprocess.run([SNAKEMAKE, "-s", str(ROOT / "Snakefile"), "-d", str(workdir), "--cores", "2", *args],
                          capture_output=True, text=True)


def planned_jobs(workdir, config):
    """(rule, output) of every job a dry run would execute for ``config``.

    The module's workdir is shared, so the tiny config is put back afterwards: a later
    test (the report, the results page) must see the outputs the fixture built.
    """
    config_file = workdir / "config.yaml"
    original = config_file.read_text()
    config_file.write_text(yaml.safe_dump(config))
    try:
        out = snakemake(workdir, "-n")
    finally:
        config_file.write_text(original)
    assert out.returncode == 0, out.stderr + out.stdout
    jobs, rule = [], None
    for line in out.stdout.splitlines():
        m = re.match(r"^(?:local)?rule (\w+):", line)
        if m:
            rule = m.group(1)
        elif line.startswith("    output:") and rule:
            jobs.append((rule, line.split(":", 1)[1].strip()))
            rule = None
        elif line.startswith("    jobid:") and rule:        # a job without outputs (rule all)
            jobs.append((rule, ""))
            rule = None
    return jobs


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    path = tmp_path_factory.mktemp("workflow")
    (path / "config.yaml").write_text(yaml.safe_dump(TINY))
    out = snakemake(path)
    assert out.returncode == 0, out.stderr[-3000:]
    return path


def test_every_dataset_has_units_long_names_and_provenance(workdir):
    files = sorted((workdir / "results").rglob("*.nc"))
    stages = set()
    for path in files:
        ds = xr.open_dataset(path)
        for name, var in ds.variables.items():
            assert "units" in var.attrs and "long_name" in var.attrs, (path, name)
        for key in ("stage", "breastcore_version", "source_hash", "config_hash", "parameters"):
            assert key in ds.attrs, (path, key)
        stages.add(ds.attrs["stage"])
        ds.close()
    assert stages == {"mesh", "solve", "measure", "identify", "sensitivity", "stability", "extreme", "calibrate",
                      "uniqueness", "scene"}


def test_solution_dataset_follows_its_contract(workdir):
    path = next(p for p in (workdir / "results/solve").glob("*.nc") if xr.load_dataset(p).sizes["posture"] == 1)
    ds = xr.load_dataset(path)
    for name, dims in {"reference_position": ("node", "xyz"), "position": ("posture", "node", "xyz"),
                       "tetrahedra": ("tet", "tet_corner"), "skin_triangles": ("skin_face", "tri_corner"),
                       "back_triangles": ("back_face", "tri_corner"), "fold": ("node",),
                       "gravity": ("posture", "xyz"), "newton_iterations": ("posture",),
                       "gradient_norm": ("posture",), "converged": ("posture",)}.items():
        assert ds[name].dims == dims
    assert ds["position"].attrs["units"] == "m" and ds["gravity"].attrs["units"] == "m s-2"
    for name in ("R", "H", "lambda_breast", "mu_breast", "lambda_skin", "mu_skin", "skin_thickness", "density",
                 "chassaignac", "smoothing"):
        assert ds[name].ndim == 0 and ds[name].attrs["units"]
    assert list(ds["posture"].values) == ["standing"]


def test_scene_outputs_exist(workdir):
    scenes = workdir / "results/scenes"
    for name in ("shape_standing.png", "shape_standing.vtu", "parameters.csv", "parameters.html", "convergence.png",
                 "diagnostics.csv", "diagnostics.html", "summary.nc"):
        assert (scenes / "alice" / name).stat().st_size > 0
    assert (scenes / "syn/sensitivity.png").exists() and (scenes / "syn/parameter_errors.csv").exists()
    assert (scenes / "syn/error_vs_runtime.png").exists()
    # loaded and closed: a handle left open by a failed assertion was seen to crash HDF5 later
    summary = xr.load_dataset(scenes / "syn/summary.nc")
    assert sorted(set(summary["method"].values)) == ["lm", "paper"]
    grid = xr.load_dataset(scenes / "grid/summary.nc")
    assert grid.sizes["case"] == 3 and set(grid["outcome"].values) <= {"converged", "solve_error"}
    assert (scenes / "grid/stability_map.png").exists() and (scenes / "grid/stability.csv").exists()
    assert grid.sizes["guess"] == 5 and set(grid["guess_outcome"].values) <= {
        "recovered", "wrong_minimum", "not_converged", "solve_error"}        # never a crash
    assert (scenes / "cal/table2_residual.png").stat().st_size > 0
    cal = xr.load_dataset(scenes / "cal/summary.nc")
    default_c = Parameters().chassaignac
    assert list(cal["chassaignac"].values) == [default_c, 1000.0] and list(cal["admissible"].values) == [1, 1, 0]
    assert cal["identification_error"].shape == (2, 1, 1) and "chosen_chassaignac" in cal.attrs
    # at the constants' c its truth solve and measurements are syn's, one job each
    shared = set(json.loads(summary.attrs["datasets"])) & set(json.loads(cal.attrs["datasets"]))
    assert sorted(p.split("/")[0] for p in shared) == ["measure", "mesh", "mesh", "solve"]
    assert not (scenes / "fwd/shape_fours.png").exists()            # not asked for: not computed
    assert not (scenes / "fwd/sensitivity.png").exists()
    assert (scenes / "alice/sensitivity.png").exists()


def test_each_scene_summary_names_its_scene(workdir):
    for name in TINY["scenes"]:
        with xr.open_dataset(workdir / f"results/scenes/{name}/summary.nc") as ds:
            assert ds.attrs["scene"] == name and ds.attrs["scene_kind"] == TINY["scenes"][name]["kind"]
            for relative in json.loads(ds.attrs["datasets"]):
                assert (workdir / "results" / relative).is_file(), (name, relative)


def test_logs_have_one_line_per_newton_and_identification_iteration(workdir):
    results = workdir / "results"
    solves = sorted((results / "solve").glob("*.nc"))
    identifications = sorted((results / "identify").glob("*.nc"))
    assert solves and identifications
    for path in solves:
        log = (results / "logs/solve" / (path.stem + ".log")).read_text()
        with xr.open_dataset(path) as ds:
            assert log.count("newton it=") == int(ds["newton_iterations"].sum()) > 0, path
    for path in identifications:
        log = (results / "logs/identify" / (path.stem + ".log")).read_text()
        with xr.open_dataset(path) as ds:
            assert log.count("identify it=") == ds.sizes["iteration"] > 1, path


def test_every_output_file_follows_the_umask(workdir):
    """netCDF datasets too: they were mode 0600 whatever the umask (issue #19, item 9)."""
    umask = os.umask(0)
    os.umask(umask)
    modes = {p.relative_to(workdir).as_posix(): stat.S_IMODE(p.stat().st_mode)
             for p in (workdir / "results").rglob("*") if p.is_file()}
    assert {Path(p).suffix for p in modes} >= {".nc", ".png", ".csv", ".vtu", ".log"}
    assert {p: oct(m) for p, m in modes.items() if m != 0o666 & ~umask} == {}


def test_second_run_does_nothing(workdir):
    jobs = planned_jobs(workdir, TINY)
    assert jobs == []


# The jobs of a patient scene with a linearised sensitivity, three postures and the report.
PATIENT_JOBS = Counter({"measure": 1, "identify": 1, "sensitivity": 1, "scene_summary": 1, "shape_picture": 3,
                        "shape_vtu": 3, "diagnostics_table": 1, "convergence_figure": 1, "parameter_table": 1,
                        "sensitivity_figure": 1})


def _new_stage_files(workdir, jobs, rules=("mesh", "solve", "measure", "identify", "sensitivity")):
    """Stage outputs among ``jobs`` must be new files: a changed spec gets a new hashed path."""
    for rule, output in jobs:
        if rule in rules:
            assert not (workdir / output).exists(), (rule, output)


#: Jobs that any change of a scene reruns: the target and the report's first page.
RUN_JOBS = Counter({"all": 1, "report_front_page": 1})


def _only_scene_jobs(workdir, jobs, scene, stages):
    """Every job is a stage job (``stages``), a run job or an output of ``scene``; stage outputs are new."""
    for rule, output in jobs:
        assert rule in (*RUN_JOBS, *stages) or output.startswith(f"results/scenes/{scene}/"), (rule, output)
    _new_stage_files(workdir, jobs)


def test_changing_one_patient_measurement_reruns_only_that_patient(workdir):
    config = copy.deepcopy(TINY)
    config["scenes"]["alice"]["postures"]["standing"]["volume"] = 650
    jobs = planned_jobs(workdir, config)
    assert Counter(r for r, _ in jobs) == PATIENT_JOBS + RUN_JOBS
    _only_scene_jobs(workdir, jobs, "alice", ("measure", "identify", "sensitivity"))


def test_changing_one_scene_mesh_reruns_only_that_scene(workdir):
    config = copy.deepcopy(TINY)
    config["scenes"]["syn"]["meshes"] = ["medium-thin"]        # a level no other scene meshes (cal has medium)
    jobs = planned_jobs(workdir, config)
    # The level mesh, the level's solve at the truth (the `levels` table), both methods'
    # identifications on it and the first one's sensitivity; the truth solve and its
    # measurements are reused. Then the scene's own outputs.
    assert Counter(r for r, _ in jobs) == RUN_JOBS + Counter({
        "mesh": 1, "solve": 1, "identify": 2, "sensitivity": 1, "scene_summary": 1,
        "convergence_figure": 1, "error_table": 1, "error_vs_runtime_figure": 1, "sensitivity_figure": 1})
    assert ("mesh", "results/mesh/medium-thin.nc") in jobs
    _only_scene_jobs(workdir, jobs, "syn", ("mesh", "solve", "identify", "sensitivity"))


def test_adding_a_patient_adds_only_its_jobs(workdir):
    config = copy.deepcopy(TINY)
    config["scenes"]["bob"] = copy.deepcopy(config["scenes"]["alice"])
    config["scenes"]["bob"]["postures"]["fours"]["height"] = 100
    jobs = planned_jobs(workdir, config)
    assert Counter(r for r, _ in jobs) == PATIENT_JOBS + RUN_JOBS
    _only_scene_jobs(workdir, jobs, "bob", ("measure", "identify", "sensitivity"))


def test_an_unchanged_patient_copy_shares_every_stage_file(workdir):
    config = copy.deepcopy(TINY)
    config["scenes"]["carol"] = copy.deepcopy(config["scenes"]["alice"])     # same data: same hashed files
    jobs = planned_jobs(workdir, config)
    assert Counter(r for r, _ in jobs) == PATIENT_JOBS - Counter({"measure": 1, "identify": 1, "sensitivity": 1}) \
        + RUN_JOBS


def test_lint_is_clean():
    out = subprocess.run([SNAKEMAKE, "--lint", "-s", str(ROOT / "Snakefile"), "-d", str(ROOT)],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "Lints for" not in out.stdout, out.stdout


def test_list_and_show_browse_every_dataset(workdir, capsys):
    from breastcore.cli.main import main
    assert main(["list", str(workdir / "results")]) == 0
    rows = {line.split()[0]: line.split()[1:] for line in capsys.readouterr().out.splitlines()[1:]}
    files = sorted((workdir / "results").rglob("*.nc"))
    assert sorted(rows) == sorted(str(p) for p in files)
    stages = {row[0] for row in rows.values()}
    assert stages == {"mesh", "solve", "measure", "identify", "sensitivity", "stability", "extreme", "calibrate",
                      "uniqueness", "scene"}
    for name in TINY["scenes"]:                                   # a summary names its own scene
        assert rows[str(workdir / f"results/scenes/{name}/summary.nc")][:2] == ["scene", name]
    # a stage dataset names the scenes it serves: the coarse mesh all four, a patient's
    # identification only that patient
    assert set(rows[str(workdir / "results/mesh/coarse.nc")][1].split(",")) == set(TINY["scenes"])
    with xr.open_dataset(workdir / "results/scenes/alice/summary.nc") as ds:
        alice = json.loads(ds.attrs["datasets"])
    assert sorted(p.split("/")[0] for p in alice) == ["identify", "measure", "mesh", "sensitivity"]
    identification = next(p for p in alice if p.startswith("identify/"))
    assert rows[str(workdir / "results" / identification)][:2] == ["identify", "alice"]
    shown = {}
    for path in files:
        assert main(["show", str(path)]) == 0
        shown[path.relative_to(workdir / "results").as_posix()] = text = capsys.readouterr().out
        assert "[stage:" in text and "provenance: breastcore" in text
    # key numbers to 4 significant digits with the names along their dimensions; a scene
    # shows the Λ that defines it
    measured = next(text for path, text in shown.items() if path.startswith("measure/") and "source: patient" in text)
    standing = TINY["scenes"]["alice"]["postures"]["standing"]
    assert f"{standing['volume'] * 1e-6:.4g}" in measured and f"{standing['area'] * 1e-4:.4g}" in measured
    postures = re.search(r"posture: (.*)\n", measured).group(1).split(", ")
    assert sorted(postures) == sorted(TINY["scenes"]["alice"]["postures"])
    assert "quantity: volume, area, height, frontal_depth, back_depth" in measured
    default = Parameters()                             # the default Λ̄ is the forward and the truth parameters
    expected = f"parameters: R={default.R:.6g} m, H={default.H:.6g} m, lambda_breast={default.lambda_breast:.6g} Pa"
    for scene in ("fwd", "syn"):
        assert expected in shown[f"scenes/{scene}/summary.nc"]
    assert "run: lm/coarse, paper/coarse" in shown["scenes/syn/summary.nc"]
    with xr.open_dataset(workdir / "results" / identification) as ds:
        assert f"parameters: R={float(ds['estimate'][0]):.6g} m" in shown["scenes/alice/summary.nc"]
    assert main(["list", str(workdir / "no-such-folder")]) == 2


def test_datasets_doc_is_rendered_from_this_workflow(workdir):
    from breastcore.report.schema_doc import render
    page = render(workdir / "results")
    doc = ROOT / "docs/datasets.md"
    if os.environ.get("BREASTCORE_WRITE_DATASETS_DOC") == "1":
        doc.write_text(page)
    assert doc.read_text() == page, "docs/datasets.md is stale: BREASTCORE_WRITE_DATASETS_DOC=1 pytest " \
                                    "tests/pipeline/test_workflow.py rewrites it"


def test_every_dataset_follows_the_documented_schema(workdir):
    from breastcore.report.schema_doc import documented_schema, section_of
    schema = documented_schema((ROOT / "docs/datasets.md").read_text())
    for path in (workdir / "results").rglob("*.nc"):
        with xr.open_dataset(path) as ds:
            documented = schema[section_of(ds)]
            for name, var in ds.variables.items():
                assert name in documented, (path, name)
                assert documented[name] == (var.dims, var.attrs["units"]), (path, name)
                # a unit per entry is comma-separated: 'm m Pa ...' would parse in UDUNITS as a product
                lists = [[str(u) for u in ds[e].values] for e in ("parameter_units", "quantity_units")
                         if e in ds and ds[e].dims[0] in var.dims]
                several = len(var.attrs["units"].replace(",", " ").split()) > 1      # not one unit for all
                if lists and several and not var.attrs["units"].startswith("products of"):
                    assert var.attrs["units"].split(", ") in lists, (path, name, var.attrs["units"])


def test_results_page_is_generated_from_scene_summaries(workdir):
    out = snakemake(workdir, "results_page")
    assert out.returncode == 0, out.stderr[-2000:]
    page = (workdir / "docs/results.md").read_text()
    assert page.startswith("# Results") and "Machine:" in page
    assert "Scene `grid`: stability" in page and "Scene `syn`: parameter error" in page
    assert "Scene `cal`: calibration of the Chassaignac coefficient c" in page and "**Rule**: the smallest c" in page
    assert "**Beside the paper's Table 1**" in page                   # the paper's Table 1 beside ours
    assert re.search(r"\| coarse +\| paper +\| +0\.08 +\| +0\.39 +\| +0\.42 +\| +0\.89 +\| +0\.27 +\| +2\.77 +\|", page)


def test_report_is_self_contained_html_with_every_figure(workdir):
    out = snakemake(workdir, "--report", "report.html")
    assert out.returncode == 0, out.stderr[-2000:]
    html = (workdir / "report.html").read_text(errors="replace")
    for caption in ("views of the skin mesh", "Identification history", "Relative sensitivity",
                    "Identified parameters", "Forward-solver diagnostics", "stability scene"):
        assert caption.lower() in html.lower(), caption
    # Snakemake's index of the report: category -> scene -> files. Each item of the issue's
    # list, for every scene that has it.
    start = html.index("var categories = ") + len("var categories = ")
    categories, _ = json.JSONDecoder().raw_decode(html, start)
    index = {(category, scene): sorted(Path(f).name for f in files)
             for category, scenes in categories.items() for scene, files in scenes.items()}
    shapes = [f"shape_{p}.png" for p in sorted(TINY["scenes"]["alice"]["postures"])]
    assert index == {
        ("Shapes", "alice"): shapes, ("Shapes", "fwd"): ["shape_standing.png"],
        ("Identification", "alice"): ["convergence.png", "parameters.html"],
        ("Identification", "syn"): ["convergence.png", "parameter_errors.html"],
        ("Sensitivity", "alice"): ["sensitivity.png"], ("Sensitivity", "syn"): ["sensitivity.png"],
        ("Solver diagnostics", "alice"): ["diagnostics.html"], ("Solver diagnostics", "fwd"): ["diagnostics.html"],
        ("Error against run time", "syn"): ["error_vs_runtime.png"],
        ("Stability", "grid"): ["stability.html", "stability_map.png"],
        ("Calibration", "cal"): ["table2_residual.png"]}


#: Debian's chromium, which `make test` installs (override: the CHROMIUM environment variable).
CHROMIUM = os.environ.get("CHROMIUM") or shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--disable-quic",
                  "--no-first-run", "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def test_a_report_before_any_run_says_it_has_no_findings(tmp_path):
    """Without results/report/front.html (no run yet, or the report turned off) the report still
    builds, and its first page says why it has no findings: docutils would fail on the missing page."""
    (tmp_path / "config.yaml").write_text(yaml.safe_dump({"report": {"enabled": False},
                                                          "scenes": {"fwd": TINY["scenes"]["fwd"]}}))
    out = snakemake(tmp_path, "--report", "r.html")
    assert out.returncode == 0, out.stderr[-2000:]
    assert "breastcore: no findings in this report" in (tmp_path / "r.html").read_text(errors="replace")


def test_the_report_opens_on_the_patient_findings_in_headless_chromium(workdir, tmp_path):
    """The report as a person sees it: rendered by its own scripts in a browser, the first page
    is breastcore's findings, the patient first, its tables as HTML rows in clinical units."""
    assert Path(CHROMIUM).exists(), "Debian's chromium is needed: `make test` installs it (apt-get install chromium)"
    out = snakemake(workdir, "--report", "browser.html")
    assert out.returncode == 0, out.stderr[-2000:]
    dom = subprocess.run([CHROMIUM, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path}", "--virtual-time-budget=20000",
                          "--dump-dom", (workdir / "browser.html").as_uri()],
                         capture_output=True, text=True, timeout=300).stdout
    # the rendered page, not the report's data: its attributes are unescaped HTML
    start = dom.index('<div class="document" id="breastcore-what-each-scene-found">')
    page = dom[start:]
    assert re.match(r'<div class="document"[^>]*>\s*<h1 class="title">breastcore: what each scene found</h1>', page)
    headings = re.findall(r"<h2[^>]*>(.*?)</h2>", page)
    assert headings[0] == "Patient alice" and "Forward solve fwd" in headings
    alice = page[:page.index(headings[1])]
    assert "Fit verdict:" in alice
    rows = [re.findall(r"<td[^>]*>(.*?)</td>", row) for row in re.findall(r"<tr[^>]*>(.*?)</tr>", alice, re.S)]
    fit = {(r[0], r[1]): r for r in rows if len(r) == 7}
    assert len(fit) == 15                                     # 5 quantities × 3 postures
    measured = TINY["scenes"]["alice"]["postures"]
    for (posture, quantity), row in fit.items():
        unit = {"volume": "ml", "area": "cm²"}.get(quantity, "mm")
        assert row[2] == unit and float(row[3]) == measured[posture][quantity], row
    assert {r[0] for r in rows if len(r) == 6} == {"R", "H", "lambda_breast", "mu_breast", "lambda_skin", "mu_skin"}
    assert len(re.findall(r'<img class="breastcore" src="data:image/png;base64,', alice)) == 3   # its shapes


def test_a_scene_plans_only_what_it_needs(tmp_path):
    """Dry runs from an empty folder: a patient scene without sensitivity plans no solve,
    no truth and no sensitivity, and shapes only its measured postures (one at its own
    angle); a forward scene solves only its listed postures; a synthetic truth solves only
    its scene's postures."""
    from breastcore.pipeline.config import validate_config
    from breastcore.pipeline.plan import Plan
    postures = dict(TINY["scenes"]["alice"]["postures"])
    postures["lean"] = {"angle": 30, **postures.pop("bent45")}       # a posture of the patient's own
    config = {"scenes": {"p": {**TINY["scenes"]["alice"], "postures": postures, "sensitivity": "none"}}}
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(config))
    out = snakemake(tmp_path, "-n")
    assert out.returncode == 0, out.stderr
    rules = Counter(re.findall(r"^(?:local)?rule (\w+):", out.stdout, re.M))
    assert rules == RUN_JOBS + Counter({"mesh": 1, "measure": 1, "identify": 1, "scene_summary": 1,
                                        "shape_picture": 3, "shape_vtu": 3, "diagnostics_table": 1,
                                        "convergence_figure": 1, "parameter_table": 1})
    assert "shape_bent45" not in out.stdout and "results/scenes/p/shape_lean.png" in out.stdout

    schema = ROOT / "workflow/schemas/config.schema.yaml"
    config = validate_config({"scenes": {
        "f": {"kind": "forward", "mesh": "coarse", "postures": ["fours", "lean=30"]},
        "s": {"kind": "synthetic", "truth_mesh": "medium", "meshes": ["coarse"], "postures": ["standing", "fours"],
              "measurement_set": "paper15", "sensitivity": "none"}}}, schema)
    plan = Plan(config)
    postures = [[p["name"] for p in spec["postures"]] for spec in plan.jobs["solve"].values()]
    assert sorted(postures) == [["fours", "lean"], ["standing", "fours"]]
    assert not plan.jobs["sensitivity"] and not plan.jobs["stability"] and not plan.jobs["extreme"]
