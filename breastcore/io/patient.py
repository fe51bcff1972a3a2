"""Patient measurements in clinical units (mm, cm², ml) from YAML, CSV or a dict, validated
into SI with one-line :class:`~breastcore.inverse.measurements.MeasurementError` messages naming the
offending item, and checked for consistency (warnings). See ``docs/measurements.md``."""

from __future__ import annotations

import csv
import dataclasses
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType as _frozen

import numpy as np
import yaml

from breastcore.inverse.measurements import QUANTITIES, UNITS, MeasurementError, check_measurement_set
from breastcore.io.yaml_keys import repeated_key
from breastcore.model.postures import PAPER_POSTURES, Posture, PostureError

KIND = _frozen({q: q if q in ("volume", "area") else "length" for q in QUANTITIES})  #: physical kind
#: Accepted units per kind and their factor to SI: ``value_SI = value × factor``.
UNIT_FACTORS = _frozen({"length": _frozen({"m": 1.0, "cm": 1e-2, "mm": 1e-3}),
                        "area": _frozen({"m2": 1.0, "cm2": 1e-4, "mm2": 1e-6}),
                        "volume": _frozen({"m3": 1.0, "l": 1e-3, "ml": 1e-6, "cm3": 1e-6})})
#: Units assumed for quantities a file does not give units for.
DEFAULT_UNITS = _frozen({"volume": "ml", "area": "cm2", "height": "mm", "frontal_depth": "mm", "back_depth": "mm"})
CONSISTENCY_FACTOR = 3.0  #: :func:`check_consistency` warns for a ratio to a cap outside [1/F, F].


class MeasurementWarning(UserWarning):
    """Physically inconsistent (but usable) patient measurements."""


class ImplausibleMeasurements(MeasurementError):
    """Measurements that no shape of the model can produce (:func:`implausible`).

    ``broken`` holds the broken rules (:func:`implausible`'s lines); :meth:`advice` words
    them with the way to run the values anyway, named as the caller's user gives it (an
    option, a config key). The message itself names the Python argument ``allow_implausible``.
    """

    def __init__(self, broken):
        self.broken = tuple(broken)
        super().__init__(self.advice("allow_implausible"))

    def __reduce__(self):                                  # pickles (e.g. from a worker process) by its rules
        return type(self), (self.broken,)

    def advice(self, allow) -> str:
        """The first broken rule, how many more, and to check them or run them flagged with ``allow``."""
        more = f" (and {len(self.broken) - 1} more)" if len(self.broken) > 1 else ""
        return f"{self.broken[0]}{more}; check the values, or run them flagged with {allow}"


@dataclass(frozen=True, eq=False)
class PatientMeasurements:
    """Measured values of one patient in SI units (arrays are read-only copies).

    Attributes
    ----------
    postures : tuple of Posture
    quantities : tuple of str, always :data:`~breastcore.inverse.measurements.QUANTITIES`.
    values : (n_posture, 5) float array, in m3, m2, m, m, m; finite and > 0.
    measurement_set : {"paper15", "exact"}
    weights : (n_posture, 5) float array, finite and >= 0; default all 1.
    notes : tuple of str
        What the input checks found and let through: implausible values run with
        ``allow_implausible`` (:func:`implausible`), and inconsistent ones
        (:func:`inconsistent`). Every output of an identification carries them.
    """

    postures: tuple
    quantities: tuple
    values: np.ndarray
    measurement_set: str = "paper15"
    weights: np.ndarray | None = None
    notes: tuple = ()

    def __post_init__(self):
        check_measurement_set(self.measurement_set)
        names = [p.name for p in self.postures]
        if tuple(self.quantities) != QUANTITIES:
            raise MeasurementError(f"quantities must be {QUANTITIES} in this order, got {tuple(self.quantities)}")
        if not names:
            raise MeasurementError("no postures: need at least one")
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise MeasurementError(f"repeated posture {', '.join(map(repr, repeated))}")
        shape = (len(names), len(QUANTITIES))
        v = np.array(self.values, dtype=float)
        w = np.ones(shape) if self.weights is None else np.array(self.weights, dtype=float)
        for what, array in (("values", v), ("weights", w)):
            if array.shape != shape:
                raise MeasurementError(f"{what} have shape {array.shape}, expected (posture, quantity) = {shape}")
        # name the first offending entry, its value in SI units, and how many others there are
        for what, array, good, rule, units in (("", v, np.isfinite(v) & (v > 0), "> 0", UNITS),
                                               (" weight", w, np.isfinite(w) & (w >= 0), ">= 0", {})):
            bad = np.argwhere(~good)
            if len(bad):
                i, j = bad[0]
                q = QUANTITIES[j]
                unit = f" {units[q]}" if q in units else ""
                more = f" (and {len(bad) - 1} more bad values)" if len(bad) > 1 else ""
                raise MeasurementError(f"posture {names[i]!r}: {q}{what} = {array[i, j]:g}{unit} "
                                       f"must be a finite number {rule}{more}")
        v.setflags(write=False), w.setflags(write=False)
        for name, value in (("values", v), ("weights", w), ("postures", tuple(self.postures)),
                            ("notes", tuple(str(n) for n in self.notes))):
            object.__setattr__(self, name, value)

    @property
    def posture_names(self) -> tuple:
        return tuple(p.name for p in self.postures)


def _unit(quantity, unit, where="") -> tuple:
    text, table = str(unit).strip().lower().replace("²", "2").replace("³", "3"), UNIT_FACTORS[KIND[quantity]]
    if text not in table:
        raise MeasurementError(f"{where}{quantity}: unknown unit {unit!r} for a {KIND[quantity]}; "
                               f"accepted: {', '.join(table)}")
    return text, table[text]


def _known(items, valid, what, hint=True):
    for item in items:
        if item not in valid:
            raise MeasurementError(f"{what} {item!r}" + (f"; valid: {', '.join(map(str, valid))}" if hint else ""))


def _mapping(obj, what, empty_ok=False):
    if not isinstance(obj, Mapping) or not (obj or empty_ok):
        raise MeasurementError(f"{what} must be a non-empty mapping, got {obj!r}")
    return obj


def _posture(name, angle=None) -> Posture:
    if angle is None and name not in PAPER_POSTURES:
        raise MeasurementError(f"unknown posture {name!r}; known: {', '.join(PAPER_POSTURES)} (or give an angle)")
    try:
        return Posture(str(name), float(PAPER_POSTURES[name] if angle is None else angle))
    except PostureError as exc:
        raise MeasurementError(str(exc)) from None
    except (TypeError, ValueError):
        raise MeasurementError(f"posture {name!r}: angle {angle!r} is not a number") from None


def _number(value, what, unit="", positive=True) -> float:
    """``value`` as a float, finite and > 0 (>= 0 if not ``positive``); the refusal names ``what``,
    the value as given and its ``unit``."""
    try:
        if isinstance(value, bool):                      # YAML's yes/no/true are not numbers
            raise TypeError
        number = float(value)
    except (TypeError, ValueError):
        raise MeasurementError(f"{what} = {value!r} is not a number") from None
    if not (math.isfinite(number) and (number > 0 if positive else number >= 0)):
        shown = str(value).strip() + (f" {unit}" if unit else "")
        raise MeasurementError(f"{what} = {shown} must be a finite number {'> 0' if positive else '>= 0'}")
    return number


def _build(table, measurement_set, weights, allow_implausible=False) -> PatientMeasurements:
    """``table``: name -> (Posture, {quantity: (value, unit)}); ``weights``: name -> {quantity: w}.

    Values that break a rule of :func:`implausible` are refused (ImplausibleMeasurements)
    unless ``allow_implausible``; then they, and the :func:`inconsistent` ones, are kept in
    ``notes``.
    """
    _known(weights, list(table), "weights: unknown posture")
    values, w = [], []
    for name, (_, given) in table.items():
        where = f"posture {name!r}: "
        _known([*given, *weights.get(name, {})], QUANTITIES, f"{where}unknown quantity")
        _known(QUANTITIES, given, f"{where}missing quantity", hint=False)
        units = {q: _unit(q, given[q][1], where) for q in QUANTITIES}     # (name, factor); checked first
        values.append([_number(given[q][0], f"{where}{q}", units[q][0]) * units[q][1] for q in QUANTITIES])
        w.append([_number(weights.get(name, {}).get(q, 1.0), f"{where}{q} weight", positive=False)
                  for q in QUANTITIES])
    result = PatientMeasurements(tuple(p for p, _ in table.values()), QUANTITIES, np.array(values),
                                 check_measurement_set(measurement_set), np.array(w))
    broken = implausible(result)
    if broken and not allow_implausible:
        raise ImplausibleMeasurements(broken)
    notes = [f"implausible, run as asked: {b}" for b in broken] + inconsistent(result)
    check_consistency(result)
    return dataclasses.replace(result, notes=tuple(notes))


def patient_from_dict(d, allow_implausible=False) -> PatientMeasurements:
    """Validate and convert the dict form (keys ``measurement_set``, ``units``, ``postures``, ``weights``).

    Raises ImplausibleMeasurements for values no shape of the model produces
    (:func:`implausible`), unless ``allow_implausible`` (they are then kept in ``notes``).
    """
    _known(_mapping(d, "patient data"), ("measurement_set", "units", "postures", "weights"), "unknown key")
    _known(_mapping(d.get("units") or {}, "units", True), QUANTITIES, "units: unknown quantity")
    units = {q: _unit(q, u, "units: ")[0] for q, u in {**DEFAULT_UNITS, **(d.get("units") or {})}.items()}
    weights = {k: _mapping(w, f"weights of posture {k!r}", True)
               for k, w in _mapping(d.get("weights") or {}, "weights", True).items()}
    table = {}
    for name, entry in _mapping(d.get("postures"), "postures").items():
        table[name] = (_posture(name, _mapping(entry, f"posture {name!r}").get("angle")),
                       {q: (v, units.get(q, "")) for q, v in entry.items() if q != "angle"})
    return _build(table, d.get("measurement_set", "paper15"), weights, allow_implausible)


def _read_csv(path, measurement_set) -> tuple:
    table, weights = {}, {}
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.DictReader(f, skipinitialspace=True)
        _known(("posture", "quantity", "value", "unit"), [h.strip() for h in reader.fieldnames or []],
               f"{path}: missing CSV column", hint=False)
        for line, row in enumerate(reader, start=2):
            row = {k.strip(): (v or "").strip() for k, v in row.items() if k}
            name, _, angle = row["posture"].partition("=")
            posture = _posture(name.strip(), angle or None)
            given = table.setdefault(posture.name, (posture, {}))[1]
            if row["quantity"] in given:
                raise MeasurementError(f"{path}:{line}: posture {posture.name!r}: "
                                       f"duplicate quantity {row['quantity']!r}")
            given[row["quantity"]] = (row["value"], row["unit"])
            if row.get("weight"):
                weights.setdefault(posture.name, {})[row["quantity"]] = row["weight"]
    return _mapping(table, f"{path}: measurements"), measurement_set, weights


def load_patient(path, measurement_set=None, allow_implausible=False) -> PatientMeasurements:
    """Read a ``.yaml``/``.yml`` (dict form) or ``.csv`` file; ``measurement_set`` (default
    the YAML file's, else ``"paper15"``) must agree with the YAML file's if both are given.
    ``allow_implausible`` as in :func:`patient_from_dict`."""
    path = Path(path)
    _known([path.suffix.lower()], (".yaml", ".yml", ".csv"), f"{path}: unknown patient file type")
    # a file that cannot be read or parsed is refused in one line too (YAML's messages span lines)
    try:
        if path.suffix.lower() == ".csv":
            return _build(*_read_csv(path, measurement_set or "paper15"), allow_implausible)
        text = path.read_text(encoding="utf-8")
        repeated = repeated_key(yaml.compose(text, Loader=yaml.SafeLoader))
        if repeated:
            raise MeasurementError(f"{path}: {repeated[0]} given twice, at lines {repeated[1]} and {repeated[2]}; "
                                   "YAML would silently keep the last")
        data = yaml.safe_load(text)
    except UnicodeDecodeError as err:
        raise MeasurementError(f"{path}: not UTF-8 text (byte {err.start})") from None
    except OSError as err:
        raise MeasurementError(f"{path}: cannot read ({err.strerror or err})") from None
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise MeasurementError(f"{path}: not valid YAML ({getattr(err, 'problem', None) or 'syntax error'}{where})") \
            from None
    if measurement_set is not None and isinstance(data, Mapping):
        if data.setdefault("measurement_set", measurement_set) != measurement_set:
            raise MeasurementError(f"{path}: measurement_set {data['measurement_set']!r} != {measurement_set!r}")
    return patient_from_dict(data, allow_implausible)


#: Ranges (SI) outside which no adult breast measures, with a wide margin: 5 ml to 20 l, 1 cm² to
#: 1 m², 5 mm to 1 m. A value outside is most likely in another unit (metres typed as mm).
ANATOMICAL_RANGE = {"volume": (5e-6, 2e-2), "area": (1e-4, 1.0), "height": (5e-3, 1.0),
                    "frontal_depth": (5e-3, 1.0), "back_depth": (5e-3, 1.0)}


def _outside_anatomy(quantity, value) -> str:
    """A message when ``value`` (SI) of ``quantity`` is outside :data:`ANATOMICAL_RANGE`, else ``""``."""
    low, high = ANATOMICAL_RANGE[quantity]
    if low <= value <= high:
        return ""
    unit = DEFAULT_UNITS[quantity]
    factor = UNIT_FACTORS[KIND[quantity]][unit]
    return (f"{quantity} {value / factor:.4g} {unit} is outside {low / factor:g} … {high / factor:g} {unit}, the "
            "range of any adult breast (a value in another unit?)")


def implausible(patient) -> list:
    """Broken rules that every measured shape of the model obeys, or values outside any breast, one
    message per break.

    Notes
    -----
    Every value must lie in :data:`ANATOMICAL_RANGE`: the rules below are invariant to scale, so
    measurements all in a wrong unit would pass them.

    With ``MP`` the nipple projection (back_depth), ``Δf`` the frontal depth, ``A`` the
    area and ``V`` the volume of the ``paper15`` set (spec §4), every deformed cap has

    - ``MP ≤ Δf``: the nipple is a point of the breast, and the frontal depth is a smooth
      maximum of ``y``, never below the largest ``y``;
    - ``A ≥ π MP²``: the rim landmarks stay in the torso plane ``y = 0``, so each of the four
      straight nipple-to-rim distances of ``A = (π/4) Σ d²`` is at least ``MP``;
    - ``V ≥ (2π/3) MP³``: each tape radius is at least its straight distance, so
      ``MR + LR + IR − MP ≥ 2 MP`` in ``V = (π/3) MP² (MR + LR + IR − MP)``.

    The ``exact`` set (a scan's mesh volume and skin area) has the first rule only.
    """
    out = []
    for name, (v, area, _h, f, mp) in zip(patient.posture_names, patient.values):
        rules = [(mp > f, f"back_depth {mp * 1e3:.4g} mm exceeds frontal_depth {f * 1e3:.4g} mm, "
                          "which is at least the nipple's projection")]
        if patient.measurement_set == "paper15":
            rules += [(area < math.pi * mp**2, f"area {area * 1e4:.4g} cm2 is below π·back_depth² = "
                                               f"{math.pi * mp**2 * 1e4:.4g} cm2 (every straight nipple-to-rim "
                                               "distance is at least the nipple projection)"),
                      (v < 2 * math.pi / 3 * mp**3, f"volume {v * 1e6:.4g} ml is below (2π/3)·back_depth³ = "
                                                   f"{2 * math.pi / 3 * mp**3 * 1e6:.4g} ml (every tape radius is "
                                                   "at least the nipple projection)")]
        out += [f"posture {name!r}: {message}" for bad, message in rules if bad]
    for name, row in zip(patient.posture_names, patient.values):      # after the rules: they say more
        out += [f"posture {name!r}: {m}" for m in (_outside_anatomy(q, x) for q, x in zip(QUANTITIES, row)) if m]
    return out


def inconsistent(patient) -> list:
    """The messages of :func:`check_consistency`, as a list (no warning issued)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeasurementWarning)
        check_consistency(patient)
    return [str(w.message) for w in caught if issubclass(w.category, MeasurementWarning)]


def check_consistency(patient) -> None:
    """Warn (:class:`MeasurementWarning`) about physically inconsistent postures.

    Notes
    -----
    The spherical cap of height ``MP`` (back_depth) and skin area ``A = π (a² + MP²)`` has
    ``V_cap = π MP (3a² + MP²) / 6``. Warn if ``V / V_cap`` or ``height / (2a)`` is outside
    ``[1/F, F]``, ``F = CONSISTENCY_FACTOR`` (3): unusual for a breast, not impossible for the
    model. What is impossible (``a² < 0``, back_depth > frontal_depth) is :func:`implausible`.
    """
    F = CONSISTENCY_FACTOR
    for name, (v, area, h, _f, mp) in zip(patient.posture_names, patient.values):
        a = math.sqrt(max(area / math.pi - mp**2, 0.0))
        v_cap = math.pi * mp * (3.0 * a * a + mp**2) / 6.0
        for bad, message in (
                (a > 0 and not 1 / F <= v / v_cap <= F, f"volume {v * 1e6:.4g} ml is not within a factor "
                 f"{F:g} of {v_cap * 1e6:.4g} ml, the spherical cap with this back_depth and area"),
                (a > 0 and not 1 / F <= h / (2 * a) <= F, f"height {h * 1e3:.4g} mm is not within a factor "
                 f"{F:g} of the base diameter {2e3 * a:.4g} mm implied by area and back_depth")):
            if bad:
                warnings.warn(f"posture {name!r}: {message}", MeasurementWarning, stacklevel=4)
