"""config.yaml validation: every bad input stops with a message naming the key."""

import copy
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from breastcore.pipeline.config import validate_config
from breastcore.pipeline.config_files import ConfigError
from breastcore.pipeline.plan import Plan

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = ROOT / "workflow/schemas/config.schema.yaml"
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
DEFAULT = yaml.safe_load((ROOT / "config.yaml").read_text())


def test_default_config_is_valid_and_defaults_are_filled():
    config = validate_config(DEFAULT, SCHEMA)
    assert config["scenes"]["paper_synthetic"]["identification"]["method"] == "lm"
    assert config["scenes"]["example_patient"]["initial"]["R"] == pytest.approx(0.0562)


def test_every_schema_key_has_a_default_or_is_required_and_a_description():
    schema = yaml.safe_load(SCHEMA.read_text())

    def walk(node, path):
        for key, sub in node.get("properties", {}).items():
            sub_path = f"{path}.{key}"
            assert "description" in sub or "$ref" in sub, sub_path
            required = key in node.get("required", []) or path.endswith("postures")
            assert "default" in sub or required or "$ref" in sub or path.startswith(".definitions.patient.postures") \
                or path.endswith(".properties") or key in ("volume", "area", "height", "frontal_depth",
                                                           "back_depth", "angle"), sub_path
            walk(sub, sub_path)
        if isinstance(node.get("additionalProperties"), dict):
            walk(node["additionalProperties"], path + ".*")

    walk(schema, "")
    for name, sub in schema["definitions"].items():
        walk(sub, f".definitions.{name}")


def _bad(mutate):
    config = copy.deepcopy(DEFAULT)
    mutate(config)
    with pytest.raises(ConfigError) as info:
        validate_config(config, SCHEMA)
    return str(info.value)


@pytest.mark.parametrize("mutate, key", [
    (lambda c: c.setdefault("solver", {}).update(rtol=5), "solver.rtol"),
    (lambda c: c["scenes"]["example_patient"].setdefault("identification", {}).update(fd_step=1.0),
     "scenes.example_patient.identification.fd_step")])
def test_the_config_bounds_what_the_command_line_bounds(mutate, key):
    """``rtol`` and ``fd_step`` are in (0, 1) on the command line; the config let 5 through."""
    message = _bad(mutate)
    assert key in message and "greater than or equal to the maximum of 1" in message, message


def test_unknown_key():
    assert "colour" in _bad(lambda c: c.update(colour="red"))
    assert "scenes.example_patient" in _bad(lambda c: c["scenes"]["example_patient"].update(nme="x"))


def test_negative_measurement():
    msg = _bad(lambda c: c["scenes"]["example_patient"]["postures"]["standing"].update(volume=-5))
    assert "scenes.example_patient.postures.standing.volume" in msg


def test_unknown_unit():
    msg = _bad(lambda c: c["scenes"]["example_patient"]["units"].update(volume="pints"))
    assert "scenes.example_patient.units.volume" in msg and "pints" in msg


def test_H_not_below_R_in_initial_guess():
    msg = _bad(lambda c: c["scenes"]["example_patient"].update(initial={"R": 0.05, "H": 0.06}))
    assert "scenes.example_patient.initial.H" in msg


def test_unknown_mesh_level_and_posture():
    assert "unknown mesh level 'huge'" in _bad(lambda c: c["scenes"]["forward_demo"].update(mesh="huge"))
    msg = _bad(lambda c: c["scenes"]["forward_demo"].update(postures=["standing", "supine"]))
    assert "scenes.forward_demo.postures" in msg and "supine" in msg
    msg = _bad(lambda c: c["scenes"]["example_patient"]["postures"].update(supine=dict(
        c["scenes"]["example_patient"]["postures"]["standing"])))
    assert "supine" in msg


def test_scene_without_measurements():
    msg = _bad(lambda c: c["scenes"]["example_patient"].update(postures={}))
    assert "scenes.example_patient.postures" in msg
    msg = _bad(lambda c: c["scenes"]["example_patient"]["postures"]["fours"].pop("height"))
    assert "missing height" in msg


def test_patient_with_one_posture_is_refused():
    msg = _bad(lambda c: c["scenes"]["example_patient"].update(
        postures={"fours": c["scenes"]["example_patient"]["postures"]["fours"]}))
    assert msg.startswith("config key scenes.example_patient.postures:") and "at least two postures" in msg


def test_an_implausible_patient_is_refused_naming_the_config_key_that_runs_it():
    msg = _bad(lambda c: c["scenes"]["example_patient"]["postures"]["standing"].update(area=1))
    assert msg.startswith("config key scenes.example_patient.postures: posture 'standing': area 1 cm2"), msg
    assert msg.endswith("run them flagged with scenes.example_patient.allow_implausible: true"), msg
    assert "--allow-implausible" not in msg


def test_non_finite_number():
    msg = _bad(lambda c: c["constants"].update(chassaignac=float("nan")))
    assert "constants.chassaignac" in msg and "finite" in msg
    msg = _bad(lambda c: c["scenes"]["example_patient"]["postures"]["bent45"].update(area=float("inf")))
    assert "scenes.example_patient.postures.bent45.area" in msg


def _negative_volume():
    config = copy.deepcopy(DEFAULT)
    config["scenes"]["example_patient"]["postures"]["standing"]["volume"] = -5
    return yaml.safe_dump(config)


def _repeated_scene():
    """config.yaml with a second scene named forward_demo written into its scenes mapping."""
    lines = (ROOT / "config.yaml").read_text().splitlines(keepends=True)
    at = lines.index("scenes:\n") + 1
    return "".join(lines[:at] + ["  forward_demo:\n", "    kind: forward\n", "    mesh: coarse\n"] + lines[at:])


def _dry_run(workdir, *args):
    return subprocess.run([SNAKEMAKE, "-n", "-s", str(ROOT / "Snakefile"), "-d", str(workdir), *args],
                          capture_output=True, text=True)


def _tab_indent():
    return (ROOT / "config.yaml").read_text().replace("    kind: forward\n", "\tkind: forward\n")


def _unclosed_list():
    return (ROOT / "config.yaml").read_text().replace("meshes: [coarse, medium]\n", "meshes: [coarse, medium\n", 1)


def _line_of(text, fragment):
    return next(i for i, line in enumerate(text().splitlines(), 1) if fragment in line)


@pytest.mark.parametrize("text, message", [
    (_negative_volume, r"config key scenes\.example_patient\.postures\.standing\.volume: -5 is less than .*"),
    (_repeated_scene, r"config key scenes\.forward_demo: given twice, at lines .*"),
    (_tab_indent, rf"config file config\.yaml, line {_line_of(_tab_indent, chr(9))}, column 1: a tab, which YAML "
                  r"does not allow as indentation \(indent with spaces\)"),
    (_unclosed_list, rf"config file config\.yaml, line {_line_of(_unclosed_list, '[coarse, medium') + 1}, column "
                     rf"\d+: expected ',' or '\]', but got ':' \(while parsing a flow sequence that starts at line "
                     rf"{_line_of(_unclosed_list, '[coarse, medium')}\)")],
    ids=["negative volume", "repeated scene", "tab indent", "unclosed list"])
def test_snakemake_stops_before_any_job_on_a_bad_config_with_one_line(tmp_path, text, message):
    """A real dry run: the error is one line on stderr, naming the key, or the file and line of
    a YAML syntax error; no Snakemake "File ..., line ..." frames (issue #19, items 7 and 10)."""
    (tmp_path / "config.yaml").write_text(text())
    out = _dry_run(tmp_path)
    assert out.returncode == 1
    assert len(out.stderr.splitlines()) == 1 and re.fullmatch("ConfigError: " + message, out.stderr.strip()), \
        out.stderr
    assert 'File "' not in out.stdout + out.stderr
    assert not (tmp_path / "results").exists()


def test_a_bad_config_on_the_command_line_is_one_line_too(tmp_path):
    (tmp_path / "config.yaml").write_text((ROOT / "config.yaml").read_text())
    out = _dry_run(tmp_path, "--config", "scenes={'x': {'kind': 'forward', 'mesh': 'huge'}}")
    assert out.returncode == 1
    assert out.stderr.splitlines() == ["ConfigError: config key scenes.x.mesh: unknown mesh level 'huge'; known: "
                                       "coarse, medium, medium-thin, thin, very-thin, ultra-thin, reference, "
                                       "fine10k, fine50k"]
    assert 'File "' not in out.stdout


def test_a_syntax_error_names_the_file_and_line(tmp_path):
    from breastcore.pipeline.config_files import check_config_files
    path = tmp_path / "c.yaml"
    for text, where in [("scenes:\n  a:\n\tkind: forward\n", "line 3, column 1: a tab"),
                        ("a: 1\n b: 2\n", "line 2, column 3: mapping values are not allowed here"),
                        ('a: "x\n', "line 2, column 1: found unexpected end of stream (while scanning a quoted "
                                     "scalar that starts at line 1)"),
                        ("a: *x\n", "line 1, column 4: found undefined alias 'x'")]:
        path.write_text(text)
        with pytest.raises(ConfigError) as info:
            check_config_files([path])
        assert str(info.value) == f"config file {path}, {where}" or str(info.value).startswith(
            f"config file {path}, {where}"), str(info.value)


def test_repeated_key_is_refused_with_both_lines(tmp_path):
    from breastcore.pipeline.config_files import check_config_files
    path = tmp_path / "c.yaml"
    path.write_text("scenes:\n  a:\n    kind: forward\n    postures: [standing]\n  b: {kind: forward}\n"
                    "  a:\n    kind: patient\n")
    with pytest.raises(ConfigError, match=r"scenes\.a: given twice, at lines 2 and 6"):
        check_config_files([path])
    path.write_text("scenes:\n  a: {kind: forward, postures: [standing, fours]}\n  b: {kind: forward}\n")
    check_config_files([path])                                   # repeated values are fine, keys are not
    fine = ["base: &b {kind: forward, mesh: coarse}\nscenes:\n  a: {<<: *b, mesh: medium}\n  b: {<<: *b}\n",
            "1: one\n'1': text one\n",                        # an integer key and a string key
            "a: &r [1, *r]\n",                                  # a self-referencing alias
            '{\n\t"scenes": {}\n}\n',                            # JSON with tabs: YAML cannot read it
            ""]
    for text in fine:
        path.write_text(text)
        check_config_files([path])


def test_results_folder_must_be_a_folder():
    for bad in ("", " ", ".", "./", "/", "//"):
        msg = _bad(lambda c: c.update(results=bad))
        assert msg.startswith("config key results:"), msg


def test_empty_scene_set_is_refused():
    assert "config key scenes: no scene" in _bad(lambda c: c.update(scenes={}))


def test_unknown_truth_mesh_names_its_own_key():
    msg = _bad(lambda c: c["scenes"]["paper_synthetic"].update(truth_mesh="huge"))
    assert msg.startswith("config key scenes.paper_synthetic.truth_mesh: unknown mesh level 'huge'"), msg
    msg = _bad(lambda c: c["scenes"]["error_vs_runtime"]["methods"][1].update(meshes=["huge"]))
    assert msg.startswith("config key scenes.error_vs_runtime.methods[1].meshes:"), msg


def test_patient_posture_key_is_a_name_with_an_optional_angle():
    values = dict(DEFAULT["scenes"]["example_patient"]["postures"]["standing"])
    msg = _bad(lambda c: c["scenes"]["example_patient"]["postures"].update({"lean=30": dict(values)}))
    assert msg.startswith("config key scenes.example_patient.postures.lean=30:") and "lean: {angle: 30" in msg
    msg = _bad(lambda c: c["scenes"]["example_patient"]["postures"].update(lean=dict(values)))
    assert "postures.lean: unknown posture 'lean'" in msg and "angle: DEGREES" in msg
    config = copy.deepcopy(DEFAULT)
    config["scenes"]["example_patient"]["postures"]["lean"] = {"angle": 30, **values}
    validate_config(config, SCHEMA)


def test_paper_posture_name_keeps_its_angle():
    msg = _bad(lambda c: c["scenes"]["example_patient"]["postures"]["standing"].update(angle=45))
    assert "scenes.example_patient.postures.standing" in msg and "0 degrees" in msg
    msg = _bad(lambda c: c["scenes"]["forward_demo"].update(postures=["fours=60"]))
    assert "scenes.forward_demo.postures" in msg and "fours" in msg
    config = copy.deepcopy(DEFAULT)
    config["scenes"]["forward_demo"]["postures"] = ["fours=90", "lean=60"]
    config["scenes"]["example_patient"]["postures"]["standing"]["angle"] = 0
    validate_config(config, SCHEMA)                                # the same angle, or a new name: fine


@pytest.mark.parametrize("written", ["1e3", "1.0e3", "1e+3"])
def test_exponent_yaml_reads_as_text_gets_a_hint_that_works(written):
    value = yaml.safe_load(f"x: {written}")["x"]
    assert value == written                                       # YAML 1.1 reads it as text
    msg = _bad(lambda c: c["scenes"]["forward_demo"]["parameters"].update(lambda_breast=value))
    assert "scenes.forward_demo.parameters.lambda_breast" in msg
    suggested = re.search(r"write (\S+),", msg).group(1)
    assert yaml.safe_load(f"x: {suggested}")["x"] == 1000.0      # the advice parses as a number
    assert "write" not in _bad(lambda c: c["scenes"]["forward_demo"]["parameters"].update(lambda_breast="660"))


def test_max_starts_keeps_the_first_guesses_of_the_full_draw():
    from breastcore.pipeline.plan import Plan
    paper = yaml.safe_load((ROOT / "config/paper.yaml").read_text())
    full = validate_config({**copy.deepcopy(DEFAULT), **paper, "scenes": paper["scenes"]}, SCHEMA)
    capped = validate_config({**copy.deepcopy(full), "max_starts": 2}, SCHEMA)
    runs_full = Plan(full).scenes["paper_table1"]["runs"]
    runs_capped = Plan(capped).scenes["paper_table1"]["runs"]
    assert len(runs_full) == 6 * 4 * 10 and len(runs_capped) == 6 * 4 * 2
    assert {r["identification"] for r in runs_capped} <= {r["identification"] for r in runs_full}
    assert {r["start"] for r in runs_capped} == {0, 1}
    assert "max_starts" in _bad(lambda c: c.update(max_starts=0))


def test_compute_hash_covers_exactly_the_modules_the_compute_rules_import(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    import breastcore
    from breastcore import _imported_modules

    (tmp_path / "__init__.py").write_text("")
    (tmp_path / "a.py").write_text("from .b import f\nfrom . import c\n")
    (tmp_path / "b.py").write_text("def f():\n    from breastcore.sub.d import g\n")
    (tmp_path / "c.py").write_text("import numpy\nfrom . import __version__\nimport breastcore.e\n")
    (tmp_path / "e.py").write_text("from breastcore import h\n")
    (tmp_path / "h.py").write_text("")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "__init__.py").write_text("")
    (tmp_path / "sub" / "d.py").write_text("from .k import x\nfrom ..h import y\n")
    (tmp_path / "sub" / "k.py").write_text("")
    (tmp_path / "report.py").write_text("from .a import f\n")
    closure = [str(p.relative_to(tmp_path)) for p in _imported_modules(tmp_path, ["a"])]
    assert closure == ["__init__.py", "a.py", "b.py", "c.py", "e.py", "h.py",
                       str(Path("sub/__init__.py")), str(Path("sub/d.py")), str(Path("sub/k.py"))]

    root = Path(breastcore.__file__).parent
    for stage in breastcore.STAGES:
        entries = [f"stages.{stage}", "pipeline.logs", "pipeline.keys"]
        names = {str(p.relative_to(root)) for p in _imported_modules(root, entries)}
        assert not names & {"report/results_page.py", "report/plots.py", "report/summaries.py", "pipeline/plan.py"}
        # every package module that importing the stage's script modules loads is in the closure
        code = f"import sys, breastcore.stages.{stage}, breastcore.pipeline.logs, breastcore.pipeline.keys; " \
               "print(' '.join(m.__file__ for n, m in sys.modules.items() if n.startswith('breastcore.')))"
        loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                check=True).stdout.split()
        assert loaded and {str(Path(f).relative_to(root)) for f in loaded} <= names, stage


@pytest.mark.parametrize("module, changed", [
    ("studies/stability.py", {"stability"}),
    ("inverse/identify.py", {"identify", "sensitivity", "extreme"}),
    ("inverse/lm.py", {"identify", "sensitivity", "extreme"}),
    ("forward/model.py", {"solve", "measure", "identify", "sensitivity", "stability", "extreme", "calibrate", "uniqueness"}),
    ("studies/extreme_guesses.py", {"extreme"}),
    ("studies/calibration.py", {"calibrate", "uniqueness"}),
    ("report/calibration.py", set()),
    ("report/results_page.py", set()),
    ("pipeline/plan.py", set()),
])
def test_editing_a_module_changes_the_code_hash_of_the_stages_that_import_it_only(tmp_path, module, changed):
    """Editing stability.py used to rerun every solve: one hash covered every compute module."""
    import shutil
    from pathlib import Path

    import breastcore
    copy_root = tmp_path / "breastcore"
    shutil.copytree(Path(breastcore.__file__).parent, copy_root, ignore=shutil.ignore_patterns("__pycache__"))
    before = {stage: breastcore.stage_hash(stage, copy_root) for stage in breastcore.STAGES}
    with open(copy_root / module, "a") as f:
        f.write("\n# an edit\n")
    after = {stage: breastcore.stage_hash(stage, copy_root) for stage in breastcore.STAGES}
    assert {stage for stage in breastcore.STAGES if before[stage] != after[stage]} == changed
    assert before == {stage: breastcore.stage_hash(stage) for stage in breastcore.STAGES}   # the copy is the package


def test_every_library_import_is_a_declared_dependency():
    """pandas and tabulate were imported (tabulate through DataFrame.to_markdown) but not declared."""
    import ast
    import re
    import sys
    from pathlib import Path

    try:
        import tomllib  # Python >= 3.11
    except ModuleNotFoundError:                          # 3.10: the same parser as tomli, if installed
        tomllib = pytest.importorskip("tomli", reason="Python 3.10 without tomli: pyproject.toml not readable")

    import breastcore
    root = Path(breastcore.__file__).parent
    project = tomllib.loads((root.parent / "pyproject.toml").read_text())["project"]
    declared = {re.split(r"[<>=;\[ ]", d, maxsplit=1)[0].lower() for d in project["dependencies"]}
    workflow = {re.split(r"[<>=;\[ ]", d, maxsplit=1)[0].lower() for d in project["optional-dependencies"]["workflow"]}
    distribution = {"yaml": "pyyaml", "netCDF4": "netcdf4"}
    for path in root.rglob("*.py"):
        source = path.read_text()
        needed = set()
        for node in ast.walk(ast.parse(source)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else []
            needed |= {n.split(".")[0] for n in names}
        needed -= set(sys.stdlib_module_names) | {"breastcore"}
        if "to_markdown" in source:
            needed.add("tabulate")
        allowed = declared | (workflow if path.relative_to(root).as_posix() == "pipeline/config.py" else set())
        missing = {distribution.get(n, n).lower() for n in needed} - allowed
        assert not missing, f"{path.name} imports {missing}, not declared in pyproject.toml"


def test_fixed_iterations_only_with_gauss_newton():
    msg = _bad(lambda c: c["scenes"]["paper_synthetic"].update(identification={"fixed_iterations": True}))
    assert "scenes.paper_synthetic.identification.fixed_iterations" in msg and "lm" in msg
    config = copy.deepcopy(DEFAULT)
    config["scenes"]["paper_synthetic"].update(identification={"fixed_iterations": True},
                                              methods=[{"name": "gn", "method": "gauss-newton"}])
    assert validate_config(config, SCHEMA)["scenes"]["paper_synthetic"]["identification"]["fixed_iterations"]


def _write_copy(tmp_path, edit, name="copy.yaml"):
    """config.yaml in ``tmp_path``, and a copy of it edited by ``edit``."""
    (tmp_path / "config.yaml").write_text((ROOT / "config.yaml").read_text())
    config = copy.deepcopy(DEFAULT)
    edit(config)
    (tmp_path / name).write_text(yaml.safe_dump(config, sort_keys=False))
    return str(tmp_path / name)


def _planned(out):
    return set(re.findall(r"^    output: (.*)$", out.stdout, re.M))


DROP = "drop it with null in copy.yaml ({}: null), or run copy.yaml alone with --replace-workflow-config"
GIVE = "give it in copy.yaml (required: null cannot drop it)"


@pytest.mark.parametrize("edit, key, advice", [
    (lambda c: c["scenes"]["example_patient"]["postures"].pop("fours"), "scenes.example_patient.postures.fours",
     DROP.format("fours")),
    (lambda c: c["scenes"]["example_patient"]["postures"]["bent45"].pop("height"),
     "scenes.example_patient.postures.bent45.height", GIVE),          # height: null would be refused
    (lambda c: c["scenes"]["example_patient"].pop("kind"), "scenes.example_patient.kind", GIVE),
    (lambda c: c["constants"].pop("chassaignac"), "constants.chassaignac", DROP.format("chassaignac"))],
    ids=["posture", "quantity", "kind", "section key"])
def test_a_partial_configfile_copy_is_refused_naming_the_key(tmp_path, edit, key, advice):
    """A real dry run of a copy of config.yaml with a key left out, which Snakemake's merge
    would silently restore from config.yaml (issue #19, item 5). Null is offered only for a
    key that may be null: ``kind: null`` or ``height: null`` would be refused next."""
    copy_file = _write_copy(tmp_path, edit)
    out = _dry_run(tmp_path, "--configfile", copy_file)
    assert out.returncode == 1, out.stdout[-2000:]
    assert out.stderr.splitlines() == [
        f"ConfigError: config key {key}: in config.yaml but left out of copy.yaml, which Snakemake merges into "
        f"config.yaml key by key, so config.yaml's value would run; {advice}"]


@pytest.mark.parametrize("edit, keys, redefined", [
    (lambda c: c["scenes"].pop("forward_demo"), "scenes.forward_demo", "scenes.paper_synthetic"),
    (lambda c: c.pop("constants"), "constants", "scenes.paper_synthetic"),
    (lambda c: [c.pop(k) for k in ("results", "solver", "constants", "report")] and
     [c["scenes"].pop(n) for n in ("paper_synthetic", "error_vs_runtime", "forward_demo")],
     "results, solver, constants, report, scenes.paper_synthetic, scenes.error_vs_runtime, scenes.forward_demo",
     "scenes.example_patient")],
    ids=["scene", "section", "all but one scene"])
def test_a_configfile_copy_that_leaves_out_a_scene_or_section_is_refused_naming_it(tmp_path, edit, keys, redefined):
    """A copy of config.yaml (it redefines one of its scenes) with a whole scene or section
    deleted: Snakemake's merge would run config.yaml's (issue #19, G1)."""
    copy_file = _write_copy(tmp_path, edit)
    out = _dry_run(tmp_path, "--configfile", copy_file)
    assert out.returncode == 1, out.stdout[-2000:]
    first = keys.split(", ")[0].rsplit(".", 1)[-1]
    one = "," not in keys
    assert out.stderr.splitlines() == [
        f"ConfigError: config key{'' if one else 's'} {keys}: in config.yaml but left out of copy.yaml, which "
        f"Snakemake merges into config.yaml key by key, so config.yaml's value{'' if one else 's'} would run "
        f"(copy.yaml redefines config.yaml's {redefined}: a copy of config.yaml, which must give or drop each "
        f"scene and section of it); drop {'it' if one else 'each'} with null in copy.yaml ({first}: null), or run "
        f"copy.yaml alone with --replace-workflow-config"]


def test_a_copy_drops_a_scene_with_null(tmp_path):
    dropped = _write_copy(tmp_path, lambda c: c["scenes"].update(forward_demo=None), "dropped.yaml")
    out = _dry_run(tmp_path, "--configfile", dropped)
    assert out.returncode == 0, out.stderr
    planned = _planned(out)
    assert any("scenes/example_patient/" in p for p in planned) and not any("forward_demo" in p for p in planned)


def test_null_is_offered_exactly_for_the_keys_that_may_be_null(tmp_path):
    """Each key a refusal says to drop with null gives a valid config when dropped; each it says to
    give would be refused by the validation if dropped."""
    from breastcore.pipeline.overlays import check_overlays, drop_keys
    base = tmp_path / "config.yaml"
    base.write_text((ROOT / "config.yaml").read_text())
    paths = [("scenes", "example_patient", "postures", "fours"), ("scenes", "example_patient", "postures"),
             ("scenes", "example_patient", "postures", "bent45", "height"), ("scenes", "example_patient", "kind"),
             ("scenes", "example_patient", "units"), ("scenes", "example_patient", "units", "volume"),
             ("scenes", "example_patient", "measurement_set"), ("scenes", "paper_synthetic", "truth", "R"),
             ("scenes", "paper_synthetic", "truth"),
             ("scenes", "forward_demo", "kind"), ("scenes", "forward_demo"), ("constants", "density"),
             ("constants",), ("report", "enabled"), ("results",)]
    offered = {}
    for path in paths:
        def edit(c, value):
            node = c
            for key in path[:-1]:
                node = node[key]
            if value == "pop":
                node.pop(path[-1])
            else:
                node[path[-1]] = value
        left_out = _write_copy(tmp_path, lambda c: edit(c, "pop"), "left_out.yaml")
        with pytest.raises(ConfigError) as info:
            check_overlays(base, [left_out], schema_path=SCHEMA)
        message = str(info.value)
        assert message.startswith(f"config key {'.'.join(path)}: "), message
        offered[path] = "with null" in message
        assert offered[path] != ("null cannot drop" in message), message
        nulled = _write_copy(tmp_path, lambda c: edit(c, None), "nulled.yaml")
        config = copy.deepcopy(DEFAULT)
        edit(config, None)
        drop_keys(config, check_overlays(base, [nulled], schema_path=SCHEMA))
        if offered[path]:
            validate_config(config, SCHEMA)
        else:
            with pytest.raises(ConfigError):
                validate_config(config, SCHEMA)
    assert {".".join(p) for p, null in offered.items() if not null} == {
        "scenes.example_patient.postures", "scenes.example_patient.postures.bent45.height",
        "scenes.example_patient.kind", "scenes.forward_demo.kind"}


def test_a_copy_drops_a_posture_with_null_or_runs_alone_with_replace_workflow_config(tmp_path):
    shape = "results/scenes/example_patient/shape_{}.png"
    dropped = _write_copy(tmp_path, lambda c: c["scenes"]["example_patient"]["postures"].update(fours=None),
                          "dropped.yaml")
    out = _dry_run(tmp_path, "--configfile", dropped)
    assert out.returncode == 0, out.stderr
    assert shape.format("standing") in _planned(out) and shape.format("fours") not in _planned(out)
    alone = _write_copy(tmp_path, lambda c: c["scenes"]["example_patient"]["postures"].pop("fours"), "alone.yaml")
    out = _dry_run(tmp_path, "--configfile", alone, "--replace-workflow-config")
    assert out.returncode == 0, out.stderr
    assert shape.format("standing") in _planned(out) and shape.format("fours") not in _planned(out)


def _readme_opt_in_commands():
    """The --configfile lists of the README's opt-in commands, with their targets."""
    text = (ROOT / "README.md").read_text()
    return sorted({(m.group(1).strip(), m.group(2).strip())
                   for m in re.finditer(r"snakemake --cores 2 ([\w ]*)--configfile ([\w/. -]+?\.yaml)(?=`|\s*(?:#|$))",
                                        text, re.M)})


def test_the_readme_names_the_opt_in_commands():
    commands = _readme_opt_in_commands()
    assert ("results_page", "config/paper.yaml") in commands and ("", "config/stability.yaml") in commands
    assert ("results_page", "config/paper.yaml config/evidence.yaml config/error_vs_runtime.yaml "
                            "config/calibration.yaml config/results.yaml") in commands


@pytest.mark.parametrize("target, files", _readme_opt_in_commands())
def test_the_opt_in_configs_still_merge_into_config_yaml(tmp_path, target, files):
    """They add scenes and set run_scenes: a real dry run of each of the README's commands."""
    (tmp_path / "config.yaml").write_text((ROOT / "config.yaml").read_text())
    out = _dry_run(tmp_path, *target.split(), "--configfile", *(str(ROOT / f) for f in files.split()))
    assert out.returncode == 0, out.stderr[-2000:]


def test_check_overlays_compares_each_file_with_what_is_merged_before_it(tmp_path):
    from breastcore.pipeline.overlays import check_overlays, drop_keys
    base = tmp_path / "config.yaml"
    base.write_text("scenes:\n  a: {kind: forward, mesh: coarse, postures: [standing]}\nsolver: {method: newton}\n")
    (tmp_path / "one.yaml").write_text("scenes:\n  b: {kind: forward, mesh: medium}\n")
    (tmp_path / "two.yaml").write_text("scenes:\n  b: {kind: forward}\n")
    # a file that redefines scene a of config.yaml is a copy: it gives (or drops) solver too
    (tmp_path / "drop.yaml").write_text("scenes:\n  a: {mesh: null, kind: forward, postures: [fours]}\n"
                                        "solver: {method: newton}\n")
    (tmp_path / "again.yaml").write_text("scenes:\n  a: {mesh: medium, kind: forward, postures: [fours]}\n"
                                         "solver: {method: newton}\n")
    (tmp_path / "gone.yaml").write_text("scenes:\n  a: null\n")
    (tmp_path / "partial.yaml").write_text("scenes:\n  a: {kind: forward}\nsolver: {method: newton}\n")
    (tmp_path / "no_solver.yaml").write_text("scenes:\n  a: {kind: forward, mesh: coarse, postures: [fours]}\n")
    (tmp_path / "solver_only.yaml").write_text("solver: {method: cg}\n")
    one, two, drop, again, gone = (str(tmp_path / f"{n}.yaml") for n in ("one", "two", "drop", "again", "gone"))
    assert check_overlays(base, [one]) == []                      # a new scene: added
    with pytest.raises(ConfigError, match=rf"^config key scenes\.b\.mesh: in {re.escape(one)} but left out of "
                                          rf"{re.escape(two)}"):
        check_overlays(base, [one, two])                          # compared with the file before it
    with pytest.raises(ConfigError, match=r"^config key scenes\.b\.mesh"):
        check_overlays(base, [one, two], replace=True)            # without config.yaml too
    with pytest.raises(ConfigError, match=r"^config keys scenes\.a\.mesh, scenes\.a\.postures: in .*config\.yaml but"):
        check_overlays(base, [two, str(tmp_path / "partial.yaml")])
    assert check_overlays(base, [two], replace=True) == []       # config.yaml discarded: nothing left out
    config = {"scenes": {"a": {"kind": "forward", "mesh": None, "postures": ["fours"]}}}
    drops = check_overlays(base, [drop])
    assert drops == [("scenes", "a", "mesh")]
    drop_keys(config, drops)
    assert config == {"scenes": {"a": {"kind": "forward", "postures": ["fours"]}}}
    config = {"scenes": {"a": {"kind": "forward", "mesh": "medium", "postures": ["fours"]}}}
    drop_keys(config, check_overlays(base, [drop, again]))       # given again by a later file: kept
    assert config["scenes"]["a"]["mesh"] == "medium"
    assert check_overlays(base, [gone]) == [("scenes", "a")]     # a scene dropped whole
    with pytest.raises(ConfigError, match=r"^config key solver: in .*config\.yaml but left out of .*no_solver\.yaml"
                                          r".* \(.*no_solver\.yaml redefines .*config\.yaml's scenes\.a: a copy"):
        check_overlays(base, [str(tmp_path / "no_solver.yaml")])  # a copy leaves out a section
    # a section given whole over config.yaml's scenes is an overlay, not a copy
    assert check_overlays(base, [str(tmp_path / "solver_only.yaml")]) == []
    assert check_overlays(base, [two, str(tmp_path / "no_solver.yaml")], replace=True) == []  # no config.yaml
    (tmp_path / "b_again.yaml").write_text("scenes:\n  b: {kind: forward, mesh: coarse}\n")
    assert check_overlays(base, [one, str(tmp_path / "b_again.yaml")]) == []   # b is not config.yaml's: no copy
    assert check_overlays(tmp_path / "missing.yaml", [two]) == []


def test_a_config_error_ends_the_program_with_one_line():
    from breastcore.pipeline.overlays import config_errors_exit
    with pytest.raises(SystemExit) as info:
        with config_errors_exit():
            raise ConfigError("config key x: bad")
    assert info.value.code == "ConfigError: config key x: bad"
    with pytest.raises(KeyError):                                 # any other error is Snakemake's to print
        with config_errors_exit():
            raise KeyError("x")


def test_same_mesh_truth_solves_each_levels_data_on_that_level():
    """The paper's Table 1 layout: each level identifies data solved on its own mesh (no gmsh truth mesh)."""
    config = copy.deepcopy(DEFAULT)
    config["scenes"]["same"] = {"kind": "synthetic", "truth_mesh": "same", "meshes": ["coarse", "medium"],
                                "offsets": [0.1, 0.3], "starts": 2}
    plan = Plan(validate_config(config, SCHEMA))
    runs = plan.scenes["same"]["runs"]
    assert len(runs) == 2 * 2 * 2
    for run in runs:
        spec = plan.jobs["identify"][run["identification"]]
        solution = plan.jobs["solve"][plan.jobs["measure"][spec["measurements"]]["solution"]]
        assert solution["mesh"] == spec["mesh"] == f"results/mesh/{run['mesh']}.nc"
        assert solution["parameters"]["mu_breast"] == 150.0
    assert not any("direct" in path for path in plan.scene_datasets("same"))
    msg = _bad(lambda c: c["scenes"].update(same={"kind": "synthetic", "truth_mesh": "same", "tables": ["levels"]}))
    assert "scenes.same.tables" in msg and "same" in msg


def test_the_schema_defaults_are_the_code_defaults():
    """One source of defaults: the schema's copies (for whoever reads the YAML) must equal
    PARAMETER_INFO and the options dataclasses, which the README's tables are generated from."""
    import dataclasses

    from breastcore.forward.options import SolverOptions
    from breastcore.inverse.options import IdentificationOptions
    from breastcore.model.parameters import IDENTIFIED, PARAMETER_INFO
    from breastcore.pipeline.config import DEFAULT_SCHEMA, load_schema

    schema = load_schema(DEFAULT_SCHEMA)
    definitions = schema["definitions"]
    constants = schema["properties"]["constants"]["properties"]
    for name, info in PARAMETER_INFO.items():
        where = definitions["lambda"]["properties"] if name in IDENTIFIED else constants
        assert where[name]["default"] == info.default, name
    for cls, section in ((SolverOptions, schema["properties"]["solver"]["properties"]),
                         (IdentificationOptions, definitions["identification"]["properties"])):
        for f in dataclasses.fields(cls):
            if f.name in section:
                assert section[f.name]["default"] == f.default, (cls.__name__, f.name)


def test_every_job_asks_a_scheduler_for_threads_memory_and_time(tmp_path):
    """A cluster executor (workflow/profiles/slurm) sizes each sbatch job from these: every job
    of the default run and of the paper scene declares mem_mb and runtime, by its stage and level."""
    import yaml

    from breastcore.pipeline.resources import mem_mb, runtime_minutes
    (tmp_path / "config.yaml").write_text((ROOT / "config.yaml").read_text())
    for extra in ([], ["results_page", "--configfile", str(ROOT / "config/paper.yaml")]):
        out = _dry_run(tmp_path, *extra)
        assert out.returncode == 0, out.stderr[-2000:]
        jobs = re.findall(r"^rule (\w+):\n(?:    .*\n)*?    output: (\S+?)(?:,.*)?\n(?:    .*\n)*?    resources: (.*)$",
                          out.stdout, re.M)
        rules = [r for r in re.findall(r"^rule (\w+):$", out.stdout, re.M) if r != "all"]    # the target only
        assert len(jobs) == len(rules) > 10
        for rule, output, resources in jobs:
            asked = dict(item.split("=", 1) for item in resources.split(", "))
            assert int(asked["mem_mb"]) > 0 and int(asked["runtime"]) > 0, (rule, resources)
            if rule == "identify" and "/ultra-thin-" in output:
                assert (int(asked["mem_mb"]), int(asked["runtime"])) == (mem_mb("ultra-thin"),
                                                                       runtime_minutes("identify", "ultra-thin"))
    profile = yaml.safe_load((ROOT / "workflow/profiles/slurm/config.yaml").read_text())
    assert profile["executor"] == "slurm" and {"mem_mb", "runtime"} <= set(profile["default-resources"])
