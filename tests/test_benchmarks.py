"""``make bench`` runs on a fresh clone: every benchmark script parses the flags the
Makefile passes it, needs no positional argument and no workflow output.

The tables themselves are not checked here (they are measurements, in
``docs/benchmarks.md``); what is checked is what made ``make bench`` fail on a fresh
clone: a script reading ``results/mesh/<level>.nc`` or another workflow file, and a
script with a required positional argument.
"""

import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "benchmarks").glob("bench_*.py"))
MAKEFILE = (ROOT / "Makefile").read_text()


def load(path):
    """Import a benchmark script as a module (its own ``sys.path`` set-up runs)."""
    spec = importlib.util.spec_from_file_location(f"benchscript_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def make_flags(target):
    """The flags the Makefile's ``target`` passes every script (``target: BENCH_FLAGS = ...``)."""
    match = re.search(rf"^{re.escape(target)}: BENCH_FLAGS =(.*)$", MAKEFILE, re.M)
    assert match, f"no BENCH_FLAGS for {target} in the Makefile"
    return match.group(1).split()


def test_make_bench_runs_every_script_in_its_quick_mode():
    assert {s.stem for s in SCRIPTS} == {"bench_cold_factorisations", "bench_cold_variants",
                                         "bench_delta_newton",
                                         "bench_factorization", "bench_forward", "bench_identify",
                                         "bench_inertia", "bench_iterative_solver", "bench_kernels",
                                         "bench_newton_floor", "bench_problem_builds", "bench_projection",
                                         "bench_relaxed_skin",
                                         "bench_solver_option",
                                         "bench_table1_variants",
                                         "bench_warm_distance", "bench_warm_radius"}
    run = MAKEFILE.split("BENCH_RUN =")[1].split("\n\n")[0]
    assert "benchmarks/bench_*.py" in run and "$(BENCH_FLAGS)" in run and "|| exit 1" in run
    assert make_flags("bench") == ["--quick"]
    assert make_flags("bench-full") == []
    for target in ("bench", "bench-full"):
        assert re.search(rf"^{re.escape(target)}: \$\(BIN\)/\.installed.*\n\t@\$\(BENCH_RUN\)$", MAKEFILE, re.M), target


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.stem)
def test_script_accepts_the_makefile_flags_and_documents_quick(script):
    module = load(script)
    assert "--quick" in module.__doc__, "the docstring says what --quick runs"
    assert module.parse_args(make_flags("bench")).quick is True          # an unknown flag would exit 2
    assert module.parse_args(make_flags("bench-full")).quick is False    # no positional argument is required


def test_help_works(capsys):
    # One interpreter per script would cost seconds each; --help in-process exits 0 the same way.
    for script in SCRIPTS:
        with pytest.raises(SystemExit) as info:
            load(script).main(["--help"])
        assert info.value.code == 0, script.name
        assert "--quick" in capsys.readouterr().out, script.name


def test_quick_defaults_leave_the_full_defaults_alone():
    """``--quick`` only fills what was not given; without it the full study's defaults hold."""
    bench = {p.stem: load(p) for p in SCRIPTS}
    ident = bench["bench_identify"].parse_args([])
    assert (ident.bench, ident.levels, ident.paper_iterations, ident.paper_timeout) == ("all", "coarse,ultra-thin",
                                                                                       10, 900.0)
    ident = bench["bench_identify"].parse_args(["--quick", "--paper-iterations", "3"])
    assert (ident.bench, ident.levels, ident.paper_iterations) == ("all", "coarse", 3)
    assert bench["bench_cold_variants"].parse_args([]).level == "medium-thin"
    assert bench["bench_cold_variants"].parse_args(["--quick", "--level", "thin"]).level == "thin"
    assert bench["bench_factorization"].parse_args([]).levels[-1] == "fine50k"
    assert "fine50k" not in bench["bench_factorization"].parse_args(["--quick"]).levels
    assert bench["bench_projection"].parse_args([]).repeats == 7
    floor = bench["bench_newton_floor"].parse_args([])
    assert (floor.levels, floor.repeats, floor.deltas) == (["ultra-thin", "reference", "fine10k"], 3, [1e-4, 1e-3])
    assert bench["bench_forward"].parse_args(["--quick"]).repeats == 3
    distance = bench["bench_warm_distance"].parse_args([])
    assert (distance.level, distance.points, distance.chains) == ("ultra-thin", 3, [3, 6])
    quick = bench["bench_warm_distance"].parse_args(["--quick"])
    assert (quick.level, quick.points) == ("coarse", 2)
    warm = bench["bench_warm_radius"].parse_args([])
    assert (warm.level, warm.starts) == ("medium-thin", 2)
    from breastcore.studies import stability_grid
    stab = stability_grid.parse_args(["--quick"])
    assert stab.out.name == "stability_quick.csv"                       # never the full grid's table
    assert stability_grid.parse_args([]).out.name == "stability.csv"


def test_cold_variants_runs_in_a_copy_without_results(tmp_path):
    """The script that read ``results/mesh/medium-thin.nc`` runs where no workflow ever ran.

    A copy of ``benchmarks/`` alone is a repository root without ``results/`` (the
    scripts find their root from their own path; breastcore is the installed package).
    """
    shutil.copytree(ROOT / "benchmarks", tmp_path / "benchmarks", ignore=shutil.ignore_patterns("results", "__pycache__"))
    out = subprocess.run([sys.executable, "benchmarks/bench_cold_variants.py", "--quick", "--variants", "default"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "### Cold solves on coarse" in out.stdout and "| default" in out.stdout
    assert not (tmp_path / "results").exists()


def test_warm_radius_builds_missing_inputs_with_the_workflow_stages(tmp_path, monkeypatch):
    """Inputs missing from ``results/`` are built by mesh → solve → measure; present ones are used."""
    from breastcore.io.datasets import open_dataset
    from breastcore.pipeline.config import validate_config
    from breastcore.pipeline.plan import Plan
    warm = load(ROOT / "benchmarks" / "bench_warm_radius.py")
    config = validate_config({"scenes": {"s": {
        "kind": "synthetic", "truth_mesh": "coarse", "meshes": ["coarse"], "postures": ["fours"],
        "measurement_set": "paper15", "sensitivity": "none"}}}, ROOT / "workflow/schemas/config.schema.yaml")
    plan = Plan(config)
    (measure_path, spec), = plan.jobs["measure"].items()
    monkeypatch.setattr(warm, "ROOT", tmp_path / "clone")                # a root without results/
    built = tmp_path / "built"
    got = Path(warm.ensure_input(plan, "measure", measure_path, built))
    assert got == built / measure_path
    assert (built / spec["solution"]).exists() and (built / plan.jobs["solve"][spec["solution"]]["mesh"]).exists()
    with open_dataset(got) as ds:
        assert ds.attrs["config_hash"] == warm.spec_key(spec)            # as the workflow's measure rule writes it
    workflow_file = tmp_path / "clone" / measure_path                    # the workflow's own file wins
    workflow_file.parent.mkdir(parents=True)
    shutil.copy(got, workflow_file)
    assert Path(warm.ensure_input(plan, "measure", measure_path, built)) == workflow_file


def test_warm_distance_directions_keep_the_cap_valid():
    """Every point of every path is a valid cap (H < R) and the direction's largest entry is 1."""
    import numpy as np
    from breastcore.model.parameters import Parameters
    distance = load(ROOT / "benchmarks" / "bench_warm_distance.py")
    for base, d in distance.directions(30):                             # seed 0 draws H ≥ R at points 5, 6, 9 …
        assert np.abs(d).max() == 1.0 and np.abs(d).min() >= 0.5
        for s in (0.01, 0.3, 1.0):
            Parameters().with_identified(base * np.exp(s * d))          # raises ParameterError if H ≥ R
    assert np.array_equal(distance.directions(2)[1][0], distance.directions(30)[1][0])   # a prefix of the sequence
    for bad in (["--points", "0"], ["--steps", "0.01,,0.02"], ["--chains", "1"], ["--smoothing", "0"]):
        with pytest.raises(SystemExit):
            distance.parse_args(bad)


def test_newton_floor_variants_differ_from_the_default_only_where_named():
    """``exact`` only drops the chord steps; ``default δ=…`` only raises δ; ``Newton δ=…`` also drops
    the chord steps, the primal-dual blocks and the releases. No δ phase: the ramp runs at
    max(δ, smoothing_start). A δ at or below the spec's is refused (it would smooth nothing)."""
    import dataclasses
    from breastcore.forward.options import SolverOptions
    from breastcore.model.parameters import Parameters
    floor = load(ROOT / "benchmarks" / "bench_newton_floor.py")
    cases = floor.variants([1e-3])
    assert list(cases) == ["default", "exact", "default δ=0.001", "Newton δ=0.001"]
    raised = dataclasses.replace(Parameters(), smoothing=1e-3)
    assert cases["default"] == (SolverOptions(), Parameters())
    assert cases["exact"] == (dataclasses.replace(SolverOptions(), reuse_factor=0.0), Parameters())
    assert cases["default δ=0.001"] == (SolverOptions(), raised)
    plain = dataclasses.replace(SolverOptions(), reuse_factor=0.0, sliding_dual=False, sliding_release=False)
    assert cases["Newton δ=0.001"] == (plain, raised)
    assert SolverOptions().smoothing_start <= Parameters().smoothing < 1e-3
    for bad in ("1e-6", "1e-7", "1e-3,1e-6"):
        with pytest.raises(SystemExit):
            floor.parse_args(["--deltas", bad])


def test_newton_floor_counts_every_numeric_factorisation_and_restores_pardiso():
    """Fresh factorisations at every Newton step, plus the inertia check at the solution: at least one
    more than the iterations; the counter is PARDISO's own, and leaving it puts PARDISO back."""
    from breastcore.linalg import pardiso
    from breastcore.model.mesh import mesh_level
    from breastcore.model.postures import paper_postures
    if not pardiso.available():
        pytest.skip("the counts are PARDISO's")
    floor = load(ROOT / "benchmarks" / "bench_newton_floor.py")
    options, params = floor.variants([1e-3])["Newton δ=0.001"]
    original = pardiso._Pardiso.factorize
    with floor._Counter() as counter:
        _, iterations, count, deepest, solution = floor.counted_solve(mesh_level("coarse"), options, params,
                                                                      paper_postures()[2], counter)
    assert pardiso._Pardiso.factorize is original
    assert solution.iterations == iterations > 0 and count >= iterations + 1 and deepest >= 0
    assert floor._spread([3, 3]) == "3" and floor._spread([4, 3, 5]) == "3-5"


def test_relaxed_skin_paths_differ_from_the_default_only_as_named():
    """The other cold paths of ``--paths``: the settings before #21, and those with the ramp at δ = 1e-3 m."""
    import dataclasses
    from breastcore.forward.options import SolverOptions
    study = load(ROOT / "benchmarks" / "bench_relaxed_skin.py")
    variants = load(ROOT / "benchmarks" / "bench_cold_variants.py")
    paths = study.path_variants()
    before = dataclasses.replace(SolverOptions(), **variants.BEFORE)
    assert paths == {"before-21": before, "ramp at δ = 1e-3 m": dataclasses.replace(before, smoothing_start=1e-3)}
    assert before != SolverOptions() and before.smoothing_start != 1e-3
    assert study.parse_args(["--paths"]).paths and not study.parse_args([]).paths
    assert list(study.MODELS) == ["spec", "relaxed"]


def test_relaxed_skin_path_table_has_a_row_per_skin_and_posture():
    """``--paths`` on coarse: 5 points × 4 other paths per posture, counted per skin."""
    from breastcore.model.mesh import mesh_level
    study = load(ROOT / "benchmarks" / "bench_relaxed_skin.py")
    rows = study.path_rows(mesh_level("coarse"))
    assert [row[:2] for row in rows] == [[skin, posture] for skin in ("spec", "relaxed")
                                         for posture in ("standing", "bent45", "fours")]
    assert all(row[2].endswith(" of 20") for row in rows)
    found = [(2e-6, -1e-7), (5e-7, 3e-17), (1e-6, 0.0)]                 # m, J: only the first is beyond 1 µm
    assert study.path_row("spec", "standing", found) == ["spec", "standing", "1 of 3", "0.002", "-1.00e-07"]
