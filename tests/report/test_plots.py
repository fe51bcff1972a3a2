"""What the report's figures draw, read back from their artists: the fold and gravity in the
shape pictures, and no distance to a final value that is a limit."""

import numpy as np
import xarray as xr

from breastcore.cli.main import main
from breastcore.io.datasets import open_dataset
from breastcore.model.parameters import IDENTIFIED
from breastcore.report.plots import convergence_figure, shape_figure


def test_shape_picture_marks_the_lowest_fold_point_and_gravity(tmp_path):
    assert main(["solve", "--mesh", "coarse", "--posture", "standing", "--out", str(tmp_path / "s.nc")]) == 0
    ds = open_dataset(tmp_path / "s.nc")
    fold_low = 1e3 * ds["reference_position"].values[ds["fold"].values.astype(bool), 2].min()
    side, front = shape_figure(ds, "standing", tmp_path / "s.png").axes
    for ax in (side, front):
        levels = [line.get_ydata()[0] for line in ax.get_lines() if line.get_linestyle() == "--"]
        assert levels == [fold_low], levels
    assert [t.get_text() for t in side.texts] == ["fold", "g"]
    # an identification has no gravity variable: the arrow comes from posture_angle, the same direction
    arrow = side.texts[1]
    angled = ds.drop_vars("gravity").assign(posture_angle=("posture", [0.0]))
    side_of_angle = shape_figure(angled, "standing", tmp_path / "a.png").axes[0]
    assert [t.get_text() for t in side_of_angle.texts] == ["fold", "g"]
    assert side_of_angle.texts[1].xy == arrow.xy


def test_diagnostics_table_headings_carry_their_units(tmp_path):
    from breastcore.report.summaries import diagnostics_table
    assert main(["solve", "--mesh", "coarse", "--posture", "fours", "--out", str(tmp_path / "s.nc")]) == 0
    columns = list(diagnostics_table(open_dataset(tmp_path / "s.nc")).columns)
    assert {"gradient_norm (N)", "tolerance (N)", "energy (J)", "torso_penetration (m)", "wall_time (s)",
            "newton_iterations", "min_det_F"} <= set(columns), columns


def test_convergence_figure_leaves_out_an_estimate_that_is_a_limit(tmp_path):
    estimate = np.array([0.06, 0.048, 165.0, 254.0, 41.7, 2e-27])
    history = np.stack([np.array([0.0562, 0.05, 1000.0, 150.0, 8000.0, 1600.0]), estimate])
    ds = xr.Dataset({"parameters": (("iteration", "parameter"), history), "estimate": (("parameter",), estimate),
                     "cost": (("iteration",), [1e-2, 1e-3]), "limit": (("parameter",), [0, 0, 0, 0, 0, -1])},
                    coords={"iteration": [0, 1], "parameter": list(IDENTIFIED)})
    left = convergence_figure([ds], tmp_path / "c.png").axes[0]
    assert [line.get_label() for line in left.get_lines()] == ["R", "H", "λ", "μ", "λ_s"]
    assert max(np.abs(line.get_ydata()).max() for line in left.get_lines()) < 2e4       # λ_s: 8000 → 41.7
    assert [t.get_text() for t in left.texts] == ["not shown, limits: μ_s → 0"]


def test_sensitivity_heatmap_keeps_small_columns_visible_beside_a_loose_modulus(tmp_path):
    """A loose λ_s (±350 % per %) made every other column white on a linear colour scale."""
    from matplotlib.colors import SymLogNorm

    from breastcore.report.plots import sensitivity_figure
    S = np.full((6, 4), 0.5)
    S[4] = [350.0, -300.0, 10.0, -2.0]
    ds = xr.Dataset({"linearised": (("parameter", "measurement"), S)},
                    coords={"parameter": list(IDENTIFIED), "measurement": ["a", "b", "c", "d"]})
    image = sensitivity_figure(ds, tmp_path / "s.png").axes[0].images[0]
    assert isinstance(image.norm, SymLogNorm) and image.norm.vmax == 350.0
    assert abs(image.norm(0.5) - 0.5) > 0.05                    # 0.5 % per % is not drawn as white
