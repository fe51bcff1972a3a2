"""The opt-in evidence configs (config/paper.yaml, config/stability.yaml,
config/error_vs_runtime.yaml) end to end at a tiny size: the same scenes, one or two
cases each on the coarse mesh, through to docs/results.md."""

import copy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")


def shrink(config):
    """The config's scenes at a tiny size: coarse (and medium) meshes, one start, few iterations
    (one for the CG baseline), one extreme-guess factor."""
    tiny = copy.deepcopy(config)
    for scene in tiny["scenes"].values():
        if scene["kind"] == "synthetic":
            scene["meshes"] = ["coarse", "medium"] if "levels" in scene.get("tables", []) else ["coarse"]
            scene["truth_mesh"] = "medium" if scene.get("truth_mesh") in ("reference", "fine10k") else "coarse"
            scene["offsets"] = scene["offsets"][:1]
            scene["starts"] = 1
            scene.setdefault("identification", {})["max_iterations"] = 2
            for method in scene.get("methods", []):
                # the paper's CG baseline costs ~10 s an iteration even on coarse
                cap = 1 if method.get("solver") == "cg" else 2
                method["max_iterations"] = min(method.get("max_iterations", cap), cap)
                if "meshes" in method:
                    method["meshes"] = ["coarse"]
        elif scene["kind"] == "stability":
            scene["meshes"], scene["sample"], scene["chunks"] = ["coarse"], 2, 1
            scene["extreme_guesses"] = [4.0]
            scene.setdefault("identification", {})["max_iterations"] = 8
            scene.pop("identification_starts", None)
    return tiny


@pytest.mark.parametrize("name", ["paper", "stability", "error_vs_runtime"])
def test_opt_in_config_runs_end_to_end_at_a_tiny_size(tmp_path, name):
    config = yaml.safe_load((ROOT / "config" / f"{name}.yaml").read_text())
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(shrink(config)))
    (tmp_path / "config.yaml").write_text((ROOT / "config.yaml").read_text())
    out = subprocess.run([SNAKEMAKE, "-s", str(ROOT / "Snakefile"), "-d", str(tmp_path), "--cores", "2",
                          "results_page", "--configfile", str(tmp_path / "config.yaml"), str(tmp_path / "tiny.yaml")],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    page = (tmp_path / "docs/results.md").read_text()
    for scene in config["run_scenes"]:
        assert f"Scene `{scene}`" in page, scene
    if name == "paper":
        assert "the paper's Table 2 layout" in page and "iterations 15–25" in page
        assert "**Beside the paper's Table 1**" in page and "**Beside the paper's annex, case B**" in page
        assert "residual_at_truth" in page and "the paper's annex layout" in page and "| Coarse (paper)" in page
        # the paper's Table 2 residual is computed from one truth solve per level, no identification
        summary = xr.open_dataset(tmp_path / "results/scenes/paper_table1/summary.nc")
        gap = summary["discretisation_error"]
        assert list(gap["level"].values) == ["coarse", "medium"] and np.all(np.isfinite(gap.values))
        assert gap.attrs["units"] == "1"
        # The tiny truth mesh is gmsh's medium mesh at Λ̄'s (R, H), which the medium level's map reproduces:
        # no gap there, while the coarse level's measurements differ.
        assert np.abs(gap.sel(level="medium").values).max() < 1e-9
        assert np.abs(gap.sel(level="coarse").values).max() > 1e-3
        assert (tmp_path / "results/sensitivity").is_dir()       # the ±10 % and linearised matrices
        for table in ("finite ±10% (ours)", "linearised (ours)", "finite − linearised (ours)", "paper (magnitudes"):
            assert f"**{table}" in page, table
        assert "rank" in page and "condition number" in page
