"""``breastcore show`` of a patient: estimate with intervals, fit verdict and measured against
fitted, in the clinical units a tape reads (issue #22)."""

import numpy as np
import xarray as xr

from breastcore.cli.browse import describe
from breastcore.model.parameters import IDENTIFIED
from breastcore.report.clinical import clinical_lines, measured_and_fitted

TRUTH = np.array([0.0562, 0.05, 1000.0, 150.0, 8000.0, 1600.0])
POSTURES, QUANTITIES = ["standing", "fours"], ["volume", "area", "height", "frontal_depth", "back_depth"]


def _patient_summary(determined=(1, 1, 0, 1, 1, 1)):
    """A patient summary: 601 ml, 250 cm², 120 mm, 50 mm, 45 mm standing; fitted 1 % high."""
    ok = np.array(determined, bool)
    measured = np.array([[601e-6, 250e-4, 0.120, 0.050, 0.045], [820e-6, 260e-4, 0.110, 0.060, 0.055]])
    ds = xr.Dataset(
        {"estimate": (("parameter",), TRUTH), "determined": (("parameter",), ok.astype(np.int8)),
         "interval_low": (("parameter",), np.where(ok, TRUTH * 0.9, np.nan)),
         "interval_high": (("parameter",), np.where(ok, TRUTH * 1.1, np.nan)),
         "interval_decades": (("parameter",), np.where(ok, 0.09, 3.5)),
         "measured": (("posture", "quantity"), measured), "fitted": (("posture", "quantity"), measured * 1.01)},
        coords={"parameter": list(IDENTIFIED), "posture": POSTURES, "quantity": QUANTITIES})
    ds.attrs = {"stage": "scene", "scene_kind": "patient", "title": "patient scene p", "verdict": "consistent",
                "verdict_message": "made up", "worst_measurements": '["fours:height"]'}
    return ds


def test_the_estimate_is_shown_in_mm_with_its_interval_or_why_it_has_none():
    lines = clinical_lines(_patient_summary())
    r = next(line for line in lines if line.strip().startswith("R "))
    assert "56.2 mm" in r and "95 %: 50.58 … 61.82 mm" in r
    lam = next(line for line in lines if line.strip().startswith("lambda_breast"))
    assert "1000 Pa" in lam and "not determined" in lam and "3.5 decades" in lam and "95 %:" not in lam


def test_measured_against_fitted_is_in_ml_cm2_and_mm():
    lines = clinical_lines(_patient_summary())
    volume = next(line for line in lines if "standing" in line and "volume (ml)" in line)
    assert volume.split()[3:6] == ["601", "607", "+1.00"], volume
    area = next(line for line in lines if "standing" in line and "area (cm²)" in line)
    assert area.split()[3:5] == ["250", "252.5"], area
    height = next(line for line in lines if "fours" in line and "height (mm)" in line)
    assert height.split()[3:5] == ["110", "111.1"] and "among the worst" in height, height


def test_show_of_a_patient_summary_starts_with_the_clinical_block_and_names_its_pictures(tmp_path):
    shown = describe(_patient_summary(), pictures=[tmp_path / "shape_standing.png"]).splitlines()
    first = [i for i, line in enumerate(shown) if "fit verdict" in line or "estimate (95 %" in line
             or "measured against fitted" in line]
    assert len(first) == 3 and first == sorted(first) and first[0] <= 3
    assert any("shape pictures:" in line and "shape_standing.png" in line for line in shown)
    assert sum("fit verdict" in line for line in shown) == 1          # said once


def test_an_identification_dataset_gives_its_fitted_values_from_the_last_iteration():
    target = np.full((2, 5), 2.0)
    ds = xr.Dataset({"target": (("posture", "quantity"), target),
                     "measurement_error": (("iteration", "posture", "quantity"), np.stack([np.full((2, 5), 0.5),
                                                                                           np.full((2, 5), -0.25)]))})
    measured, fitted = measured_and_fitted(ds)
    np.testing.assert_array_equal(measured, target)
    np.testing.assert_array_equal(fitted, np.full((2, 5), 1.5))


def test_measure_echoes_a_patient_in_the_units_of_the_tape(tmp_path, capsys):
    """It echoed 0.000601 m3 for 601 ml; the dataset itself stays in SI."""
    from breastcore.cli.main import main
    from breastcore.io.datasets import open_dataset
    patient = tmp_path / "p.yaml"
    patient.write_text("postures:\n"
                       "  standing: {volume: 601, area: 250, height: 120, frontal_depth: 50, back_depth: 45}\n"
                       "  fours: {volume: 820, area: 262, height: 110, frontal_depth: 60, back_depth: 55}\n")
    assert main(["measure", "--patient", str(patient), "--out", str(tmp_path / "m.nc")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split() == ["volume", "[ml]", "area", "[cm²]", "height", "[mm]", "frontal_depth", "[mm]",
                              "back_depth", "[mm]"]
    assert next(line for line in out if line.startswith("standing")).split()[1:] == ["601", "250", "120", "50", "45"]
    ds = open_dataset(tmp_path / "m.nc")
    assert float(ds["measurement"].sel(posture="standing", quantity="volume")) == 601e-6


def test_the_vtu_export_carries_det_f_and_the_largest_stretch_per_cell(tmp_path):
    """A homogeneous stretch diag(1.2, 1, 0.9) of every tet: det F = 1.08, largest stretch 1.2."""
    import meshio

    from breastcore.io.export import cell_kinematics, export_solution
    reference = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    position = reference * np.array([1.2, 1.0, 0.9])
    det_F, stretch = cell_kinematics(reference, position, tets)
    np.testing.assert_allclose(det_F, 1.08, rtol=1e-14)
    np.testing.assert_allclose(stretch, 1.2, rtol=1e-14)
    ds = xr.Dataset({"position": (("posture", "node", "xyz"), position[None]),
                     "reference_position": (("node", "xyz"), reference),
                     "tetrahedra": (("tet", "corner"), tets), "fold": (("node",), np.zeros(5, np.int8))},
                    coords={"posture": ["standing"]})
    path, = export_solution(ds, tmp_path, "shape")
    mesh = meshio.read(path)
    np.testing.assert_allclose(mesh.cell_data["det_F"][0], 1.08, rtol=1e-12)
    np.testing.assert_allclose(mesh.cell_data["max_stretch"][0], 1.2, rtol=1e-12)
    np.testing.assert_allclose(mesh.point_data["displacement_m"], position - reference)


def test_parameter_errors_csv_names_a_unit_in_every_column():
    """It mixed per cent (errors) and fractions (the residual) without saying which."""
    from breastcore.report.summaries import error_table, error_table_with_units
    n = 2
    summary = xr.Dataset({"relative_error": (("run", "parameter"), np.array([[0.02] * 6, [-0.02] * 6])),
                          "measurement_residual": (("run",), np.full(n, 0.003)),
                          "method": (("run",), ["lm"] * n), "mesh": (("run",), ["coarse"] * n),
                          "offset": (("run",), [0.3] * n), "wall_time": (("run",), [1.0, 3.0]),
                          "iterations": (("run",), [4, 6]), "verdict": (("run",), ["consistent", "misfit"])},
                         coords={"parameter": list(IDENTIFIED)})
    table = error_table_with_units(summary)
    assert all(c.endswith(("(%)", "(s)", "(runs)", "(mean count)")) for c in table.columns), list(table.columns)
    assert table.index.names == ["method", "mesh", "initial offset (fraction)"]
    row = table.iloc[0]                                  # the mean of |+2 %| and |−2 %|, named so
    assert row["R |error| (%)"] == 2.0 and row["RMS measurement residual (%)"] == 0.3 and row["wall time (s)"] == 2.0
    assert error_table(summary).iloc[0]["residual"] == 0.003          # the results page's table is unchanged
