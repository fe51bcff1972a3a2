"""Patient input files: unit conversion, YAML/CSV/dict equivalence, validation
messages that name the item, and consistency warnings."""

import copy
import math
import warnings

import numpy as np
import pytest
import yaml

from breastcore.inverse.measurements import QUANTITIES, MeasurementError
from breastcore.io.patient import (
    DEFAULT_UNITS,
    UNIT_FACTORS,
    ImplausibleMeasurements,
    MeasurementWarning,
    PatientMeasurements,
    check_consistency,
    load_patient,
    patient_from_dict,
)
from breastcore.model.postures import Posture

# Plausible values (implausible()): volume ≥ (2π/3) back_depth³ and area ≥ π back_depth² in every posture.
ROWS = {"standing": (600, 310, 150, 62, 55), "bent45": (1100, 320, 140, 75, 70), "fours": (1400, 330, 130, 85, 80)}
SI = np.array([[6.0e-4, 0.031, 0.150, 0.062, 0.055],
               [1.1e-3, 0.032, 0.140, 0.075, 0.070],
               [1.4e-3, 0.033, 0.130, 0.085, 0.080]])


def good():
    return {"measurement_set": "paper15",
            "units": {"volume": "ml", "area": "cm2", "height": "mm", "frontal_depth": "mm", "back_depth": "mm"},
            "postures": {p: dict(zip(QUANTITIES, v)) for p, v in ROWS.items()}}


def csv_text(rows=ROWS, units=("ml", "cm2", "mm", "mm", "mm")):
    lines = ["posture,quantity,value,unit"]
    lines += [f"{p},{q},{v},{u}" for p, vals in rows.items() for q, v, u in zip(QUANTITIES, vals, units)]
    return "\n".join(lines) + "\n"


@pytest.fixture(autouse=True)
def no_stray_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error", MeasurementWarning)
        yield


def test_yaml_file_converts_to_si(tmp_path):
    path = tmp_path / "patient.yaml"
    path.write_text(yaml.safe_dump(good(), sort_keys=False))
    pm = load_patient(path)
    assert pm.posture_names == ("standing", "bent45", "fours")
    assert pm.postures[1] == Posture("bent45", 45.0)
    assert pm.quantities == QUANTITIES and pm.measurement_set == "paper15"
    np.testing.assert_allclose(pm.values, SI, rtol=1e-14)
    assert pm.values[0, 0] == pytest.approx(6.0e-4) and pm.values[0, 1] == pytest.approx(0.031)
    assert pm.values[0, 3] == pytest.approx(0.062)
    np.testing.assert_array_equal(pm.weights, np.ones((3, 5)))
    with pytest.raises(ValueError):
        pm.values[0, 0] = 1.0  # read-only


def test_csv_yaml_and_dict_agree(tmp_path):
    (tmp_path / "p.csv").write_text(csv_text())
    data = good()
    del data["units"], data["measurement_set"]  # defaults: ml, cm2, mm; paper15
    (tmp_path / "p.yml").write_text(yaml.safe_dump(data, sort_keys=False))
    results = [load_patient(tmp_path / "p.csv"), load_patient(tmp_path / "p.yml"), patient_from_dict(good())]
    for pm in results:
        np.testing.assert_allclose(pm.values, SI, rtol=1e-14)
        assert pm.posture_names == results[0].posture_names and pm.measurement_set == "paper15"


def test_csv_other_units_weights_and_angle(tmp_path):
    rows = {"standing": (0.6, 31000, 15, 6.2, 5.5), "seated=30": (0.6, 31000, 15, 6.2, 5.5)}
    text = csv_text(rows, units=("l", "mm2", "cm", "cm", "cm")).replace("unit\n", "unit,weight\n", 1)
    text = text.replace(",l\n", ",l,2\n", 1)
    (tmp_path / "p.csv").write_text(text)
    pm = load_patient(tmp_path / "p.csv", measurement_set="exact")
    assert pm.postures == (Posture("standing", 0.0), Posture("seated", 30.0))
    np.testing.assert_allclose(pm.values, np.tile(SI[0], (2, 1)), rtol=1e-14)
    assert pm.weights[0, 0] == 2.0 and pm.weights.sum() == 11.0 and pm.measurement_set == "exact"


@pytest.mark.parametrize("quantity, unit, value, si", [
    ("volume", "m3", 1.4e-3, 1.4e-3), ("volume", "cm3", 1400, 1.4e-3), ("volume", "mL", 1400, 1.4e-3),
    ("volume", "l", 1.4, 1.4e-3), ("area", "m2", 0.031, 0.031), ("area", "cm²", 310, 0.031),
    ("area", "mm2", 31000, 0.031), ("height", "cm", 15, 0.15), ("height", "m", 0.15, 0.15),
    ("back_depth", "mm", 55, 0.055)])
def test_unit_table(quantity, unit, value, si):
    data = good()
    data["units"][quantity] = unit
    for entry in data["postures"].values():
        entry[quantity] = value
    assert patient_from_dict(data).values[0, QUANTITIES.index(quantity)] == pytest.approx(si, rel=1e-14)
    assert set(DEFAULT_UNITS.values()) <= set().union(*UNIT_FACTORS.values())


def test_angle_posture_and_weights_in_dict():
    data = good()
    data["postures"]["tilt"] = {"angle": 30, **data["postures"]["bent45"]}
    data["weights"] = {"tilt": {"volume": 0.5}, "fours": {"height": 0}}
    pm = patient_from_dict(data)
    assert pm.postures[-1] == Posture("tilt", 30.0)
    assert pm.weights[3, 0] == 0.5 and pm.weights[2, 2] == 0.0 and pm.weights.sum() == 18.5


def _set(path, value):
    def change(d):
        *keys, last = path
        for k in keys:
            d = d[k]
        if value is KeyError:
            del d[last]
        else:
            d[last] = value
    return change


BAD = {
    "zero value": (_set(["postures", "standing", "volume"], 0), ["standing", "volume"]),
    "negative value": (_set(["postures", "fours", "height"], -3), ["fours", "height"]),
    "nan value": (_set(["postures", "bent45", "area"], math.nan), ["bent45", "area"]),
    "inf value": (_set(["postures", "bent45", "back_depth"], math.inf), ["bent45", "back_depth"]),
    "text value": (_set(["postures", "standing", "height"], "tall"), ["standing", "height", "tall"]),
    "bool value": (_set(["postures", "standing", "height"], True), ["standing", "height"]),
    "unknown posture": (_set(["postures", "sitting"], dict(zip(QUANTITIES, ROWS["fours"]))), ["sitting"]),
    "bad angle": (_set(["postures", "sitting"], {"angle": 120, **dict(zip(QUANTITIES, ROWS["fours"]))}),
                  ["sitting", "120"]),
    "paper posture at another angle": (_set(["postures", "standing", "angle"], 45), ["standing", "45"]),
    "unknown quantity": (_set(["postures", "fours", "volumen"], 480), ["fours", "volumen"]),
    "missing quantity": (_set(["postures", "bent45", "frontal_depth"], KeyError), ["bent45", "frontal_depth"]),
    "unknown unit": (_set(["units", "height"], "inch"), ["height", "inch"]),
    "unit of wrong kind": (_set(["units", "volume"], "cm2"), ["volume", "cm2"]),
    "unknown unit quantity": (_set(["units", "weight"], "kg"), ["weight"]),
    "unknown set": (_set(["measurement_set"], "paper16"), ["paper16"]),
    "unknown key": (_set(["posture"], {}), ["posture"]),
    "no postures": (_set(["postures"], {}), ["postures"]),
    "negative weight": (_set(["weights"], {"fours": {"area": -1}}), ["fours", "area", "weight"]),
    "weight for unknown posture": (_set(["weights"], {"supine": {"area": 1}}), ["supine"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_names_the_item(case):
    change, names = BAD[case]
    data = copy.deepcopy(good())
    change(data)
    with pytest.raises(MeasurementError) as err:
        patient_from_dict(data)
    message = str(err.value)
    assert "\n" not in message
    for name in names:
        assert name in message, (case, message)


@pytest.mark.parametrize("text, names", [
    ("posture,quantity,value\nstanding,volume,480\n", ["unit"]),
    (csv_text() + "standing,volume,500,ml\n", ["standing", "volume", "duplicate"]),
    (csv_text().replace("fours,height,130,mm", "fours,height,130,ft"), ["fours", "height", "ft"]),
    (csv_text().replace("fours,", "supine,"), ["supine"]),
    (csv_text().replace("fours,area,330", "fours,area,-330"), ["fours", "area"]),
    ("posture,quantity,value,unit\n", ["measurements"]),
])
def test_bad_csv_names_the_item(tmp_path, text, names):
    (tmp_path / "p.csv").write_text(text)
    with pytest.raises(MeasurementError) as err:
        load_patient(tmp_path / "p.csv")
    assert "\n" not in str(err.value) and all(n in str(err.value) for n in names), str(err.value)


def test_file_level_errors(tmp_path):
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(good(), sort_keys=False))
    with pytest.raises(MeasurementError, match="exact"):
        load_patient(tmp_path / "p.yaml", measurement_set="exact")
    with pytest.raises(MeasurementError, match=r"\.txt"):
        load_patient(tmp_path / "p.txt")
    with pytest.raises(MeasurementError, match="patient data"):
        patient_from_dict([1, 2])


@pytest.mark.parametrize("quantity, value, words", [
    ("volume", 5000, ["volume"]),                           # 5 l for a 310 cm2 breast
    ("area", 3000, ["volume"]),                             # plausible, but a wide cap for 600 ml
    ("height", 600, ["height"]),
    ("height", 40, ["height"]),
])
def test_inconsistent_input_warns_and_is_kept_in_the_notes(quantity, value, words):
    data = good()
    data["postures"]["standing"][quantity] = value
    with warnings.catch_warnings():
        warnings.simplefilter("default", MeasurementWarning)
        with pytest.warns(MeasurementWarning) as record:
            pm = patient_from_dict(data)
    messages = " ".join(str(w.message) for w in record)
    assert "standing" in messages and all(w in messages for w in words), messages
    assert pm.values.shape == (3, 5)  # still usable
    assert any("standing" in note and words[0] in note for note in pm.notes)   # every output carries it


@pytest.mark.parametrize("quantity, value, words", [
    ("back_depth", 70, ["back_depth 70 mm exceeds frontal_depth 62 mm"]),       # nipple in front of the front
    ("area", 1, ["area 1 cm2 is below π·back_depth² = 95.03 cm2"]),             # issue #19: 1 cm², 601 ml
    ("area", 90, ["area 90 cm2"]),
    ("volume", 300, ["volume 300 ml is below (2π/3)·back_depth³ = 348.5 ml"]),
])
def test_implausible_input_is_refused_with_the_rule_and_values_unless_allowed(quantity, value, words):
    data = good()
    data["postures"]["standing"][quantity] = value
    with pytest.raises(ImplausibleMeasurements) as err:
        patient_from_dict(data)
    assert "posture 'standing'" in str(err.value) and all(w in str(err.value) for w in words), str(err.value)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MeasurementWarning)
        pm = patient_from_dict(data, allow_implausible=True)
    assert any(note.startswith("implausible, run as asked: posture 'standing'") and words[0] in note
               for note in pm.notes), pm.notes


def test_the_rules_hold_for_the_models_own_measurements():
    """Every cap of the model obeys them: the paper's Λ̄ solved on coarse, in all three postures."""
    from breastcore.forward.model import ForwardModel
    from breastcore.inverse.measurements import measure
    from breastcore.io.patient import implausible
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    from breastcore.model.postures import paper_postures
    mesh = mesh_level("coarse")
    model = ForwardModel(mesh)
    for params in (Parameters(), Parameters(R=0.07, H=0.03, mu_breast=40.0)):
        values = []
        for posture in paper_postures():
            m = measure(mesh, model.solve(params, posture).position, "paper15")
            values.append([m[q] for q in QUANTITIES])
        measured = PatientMeasurements(paper_postures(), QUANTITIES, np.array(values))
        assert implausible(measured) == []
        bound = np.array(values)
        assert np.all(bound[:, 1] >= np.pi * bound[:, 4] ** 2) and np.all(bound[:, 0] >= 2 * np.pi / 3 * bound[:, 4] ** 3)


def test_dataclass_validation_and_direct_check():
    postures = (Posture("standing", 0.0),)
    pm = PatientMeasurements(postures, QUANTITIES, SI[:1])
    assert pm.measurement_set == "paper15" and np.array_equal(pm.weights, np.ones((1, 5)))
    check_consistency(pm)  # consistent: no warning (warnings are errors here)
    for bad in (dict(values=-SI[:1]), dict(values=SI), dict(measurement_set="scan"),
                dict(weights=np.full((1, 5), np.nan))):
        kwargs = dict(postures=postures, quantities=QUANTITIES, values=SI[:1]) | bad
        with pytest.raises(MeasurementError):
            PatientMeasurements(**kwargs)


@pytest.mark.parametrize("change, words", [
    (dict(values=np.zeros((1, 5))), ["'standing'", "volume = 0 m3", "> 0", "(and 4 more bad values)"]),    # all zero
    (dict(values=np.full((1, 5), np.nan)), ["'standing'", "volume = nan m3"]),
    (dict(values=SI[:1] * [1, 1, 1, -1, 1]), ["'standing'", "frontal_depth = -0.062 m "]),
    (dict(values=SI[:1] * [1, 1, 1, 1, np.inf]), ["'standing'", "back_depth = inf m "]),
    (dict(weights=[[1, 1, np.nan, 1, 1]]), ["'standing'", "height weight = nan", ">= 0"]),
    (dict(weights=[[1, -2, 1, 1, 1]]), ["'standing'", "area weight = -2"]),
    (dict(values=SI), ["values", "(3, 5)", "(1, 5)"]),
    (dict(weights=np.ones(5)), ["weights", "(5,)", "(1, 5)"]),
    (dict(postures=(Posture("standing", 0.0),) * 2, values=SI[:2]), ["repeated posture 'standing'"]),
    (dict(postures=(), values=np.zeros((0, 5))), ["no postures"]),
    (dict(quantities=QUANTITIES[::-1]), ["quantities", "back_depth"]),
])
def test_dataclass_refusal_names_the_offending_entry(change, words):
    kwargs = dict(postures=(Posture("standing", 0.0),), quantities=QUANTITIES, values=SI[:1]) | change
    with pytest.raises(MeasurementError) as err:
        PatientMeasurements(**kwargs)
    assert "\n" not in str(err.value) and all(w in str(err.value) for w in words), str(err.value)


@pytest.mark.parametrize("value, shown", [(-5, "-5 ml"), (0, "0 ml"), (math.nan, "nan ml"), ("-5", "-5 ml")])
def test_file_refusal_gives_the_value_in_its_units(value, shown):
    data = good()
    data["postures"]["standing"]["volume"] = value
    with pytest.raises(MeasurementError, match=f"posture 'standing': volume = {shown} must be a finite number > 0"):
        patient_from_dict(data)


def test_unreadable_patient_files_are_one_line(tmp_path):
    (tmp_path / "p.yaml").write_text("postures:\n  standing: {volume: 480\n")
    (tmp_path / "p.csv").write_bytes(b"posture,quantity,value,unit\nstanding,volume,480,\xb5l\n")
    for name, words in (("p.yaml", ["p.yaml", "not valid YAML", "line 3"]), ("p.csv", ["p.csv", "not UTF-8"])):
        with pytest.raises(MeasurementError) as err:
            load_patient(tmp_path / name)
        assert "\n" not in str(err.value) and all(w in str(err.value) for w in words), str(err.value)


def test_the_documented_yaml_example_is_a_patient_the_command_line_accepts(tmp_path):
    """docs/measurements.md's YAML example, as written there: loaded without a warning and measured by
    ``breastcore measure --patient`` (which refuses implausible values), to the SI values it states."""
    import re
    from pathlib import Path

    from breastcore.cli.main import main
    from breastcore.io.datasets import open_dataset
    page = (Path(__file__).parents[2] / "docs/measurements.md").read_text()
    block = re.search(r"### YAML \(or dict\)\s+```yaml\n(.*?)```", page, re.S).group(1)
    path = tmp_path / "patient.yaml"
    path.write_text(block)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        patient = load_patient(path)
    assert [p.name for p in patient.postures] == ["standing", "bent45", "fours", "seated"]
    assert patient.values[0, 0] == pytest.approx(529e-6) and patient.weights[0, 0] == 2.0
    assert main(["measure", "--patient", str(path), "--out", str(tmp_path / "m.nc")]) == 0
    stored = open_dataset(tmp_path / "m.nc")
    assert np.allclose(stored["measurement"].values, patient.values)


@pytest.mark.parametrize("scale, first", [
    ((1e-6, 1e-4, 1e-3, 1e-3, 1e-3), "volume 0.0006 ml is outside 5 … 20000 ml"),     # SI values under ml, cm², mm
    ((1.0, 1.0, 1e-3, 1e-3, 1e-3), "height 0.15 mm is outside 5 … 1000 mm"),         # lengths in metres
    ((1e3, 1.0, 1.0, 1.0, 1.0), "volume 6e+05 ml is outside 5 … 20000 ml"),           # litres typed as ml ×1000
])
def test_values_in_another_unit_are_refused_though_the_scale_free_rules_pass(scale, first):
    """The rules of implausible() compare the values with one another; a file all in a wrong unit
    passed them (a review's SI file ran 28 s and crashed). Values outside any breast are refused."""
    from breastcore.io.patient import ANATOMICAL_RANGE, implausible
    data = good()
    for posture in data["postures"].values():
        for quantity, factor in zip(QUANTITIES, scale):
            posture[quantity] *= factor
    with pytest.raises(ImplausibleMeasurements) as err:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MeasurementWarning)
            patient_from_dict(data)
    assert "posture 'standing': " + first in str(err.value), str(err.value)
    assert set(ANATOMICAL_RANGE) == set(QUANTITIES)
    assert implausible(patient_from_dict(good())) == []


def test_a_posture_or_quantity_given_twice_in_yaml_is_refused_naming_both_lines(tmp_path):
    """YAML keeps the last of two equal keys: a second 'standing' line silently replaced the first."""
    path = tmp_path / "p.yaml"
    rows = "".join(f"  {p}: {{{', '.join(f'{q}: {v}' for q, v in zip(QUANTITIES, vals))}}}\n"
                   for p, vals in ROWS.items())
    path.write_text("postures:\n" + rows + "  standing: {volume: 700, area: 310, height: 150, frontal_depth: 62, "
                    "back_depth: 55}\n")
    with pytest.raises(MeasurementError, match=r"postures\.standing given twice, at lines 2 and 5"):
        load_patient(path)
    path.write_text("postures:\n" + rows.replace("volume: 600,", "volume: 600, volume: 650,"))
    with pytest.raises(MeasurementError, match=r"postures\.standing\.volume given twice, at lines 2 and 2"):
        load_patient(path)
