"""The rule that picks the default Chassaignac coefficient c from a calibration study (issue #18).

A pure function of a table of checks, so that it can be tested on tables made by hand;
:func:`breastcore.report.calibration.criteria_table` makes the table from the
calibration scene's datasets.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

#: The three criteria: name -> (tag, what is checked, comparison). A row passes when its
#: value is finite and ``value >= bound`` (``">="``) or ``value <= bound`` (``"<="``).
CRITERIA = {
    "min_det_F": ("(a)", "standing min det F", ">="),
    "sliding_difference": ("(b)", "part of the largest relative measurement difference from the reference level "
                                  "that the back's sliding adds", "<="),
    "nonlinearity": ("(c)", "uniqueness-probe nonlinearity", "<="),
}
#: Columns a table of checks must have.
COLUMNS = ("chassaignac", "criterion", "where", "value")


class CalibrationError(ValueError):
    """A table of checks the rule cannot read (missing columns, unknown criteria, bad c values)."""


@dataclass(frozen=True)
class ChassaignacChoice:
    """The outcome of :func:`choose_chassaignac`.

    Attributes
    ----------
    chassaignac : float or None
        The chosen c (Pa): the smallest c of the table that passes every criterion;
        None when none does.
    passed : dict
        ``{c: {criterion: bool}}`` for every c of the table.
    failures : dict
        ``{c: [str]}``: one sentence per failed criterion, naming the worst row and
        where it is (empty for a c that passes).
    table : pandas.DataFrame
        The input rows with a ``bound`` and a boolean ``passed`` column.
    """

    chassaignac: float | None
    passed: dict = field(default_factory=dict)
    failures: dict = field(default_factory=dict)
    table: pd.DataFrame | None = None

    def describe(self) -> str:
        """One sentence: the chosen value, or that no c of the grid satisfies the rule."""
        if self.chassaignac is None:
            return f"no c of the grid ({', '.join(f'{c:g}' for c in self.passed)} Pa) satisfies the rule"
        return f"c = {self.chassaignac:g} Pa, the smallest c of the grid that satisfies the rule"


def choose_chassaignac(table, *, min_det_F=0.01, max_sliding_difference=0.01, linear_threshold=1e-8) -> ChassaignacChoice:
    """The smallest c whose every check passes, with the failures of the others.

    Parameters
    ----------
    table : pandas.DataFrame
        One row per check, columns :data:`COLUMNS`: ``chassaignac`` (c, Pa),
        ``criterion`` (a key of :data:`CRITERIA`), ``where`` (text naming the
        level, point or parameter) and ``value``. NaN values (a solve that did not
        converge) fail.
    min_det_F : float
        Bound of criterion (a): every row ``min_det_F`` must be ``>=`` it.
    max_sliding_difference : float
        Bound of criterion (b): every row ``sliding_difference`` must be ``<=`` it.
    linear_threshold : float
        Bound of criterion (c): every row ``nonlinearity`` must be ``<=`` it.

    Returns
    -------
    ChassaignacChoice

    Raises
    ------
    CalibrationError
        A missing column, an unknown criterion, or a c that is not a finite number.

    Notes
    -----
    A c passes when, for each of the three criteria, it has at least one row and
    every row passes:

    (a) ``min det F ≥ min_det_F`` in the standing posture on every level up to the
        reference, at Λ̄ and every box corner: no tet crushed against the fold;
    (b) the sliding difference ``≤ max_sliding_difference`` at Λ̄ and every box corner:
        ``d(c, p) − d(c_max, p)``, where ``d(c, p) = max_i |M_i(compare level)/M_i(reference) − 1|``
        and ``c_max`` is the largest c of the grid, on whose back nothing slides: what
        ``d`` keeps there is the meshes' own discretisation error, which no c removes,
        and the excess over it is what sliding adds (the rows carry it; the table
        maker computes it, :func:`breastcore.report.calibration.criteria_table`);
    (c) the nonlinearity of every parameter's uniqueness probe at Λ̄ is
        ``≤ linear_threshold``: ``M(Λ)`` is smooth there, no branch jump.

    The chosen c is the smallest passing one, whether or not a larger c fails
    (the table says so in ``passed``).
    """
    if not isinstance(table, pd.DataFrame):
        table = pd.DataFrame(table)
    missing = [c for c in COLUMNS if c not in table.columns]
    if missing:
        raise CalibrationError(f"table of checks without column(s) {', '.join(missing)}")
    unknown = sorted(set(table["criterion"]) - set(CRITERIA))
    if unknown:
        raise CalibrationError(f"unknown criterion {unknown[0]!r}; criteria: {', '.join(CRITERIA)}")
    try:
        c_values = table["chassaignac"].astype(float)
    except (TypeError, ValueError) as err:
        raise CalibrationError(f"chassaignac values must be numbers: {err}") from None
    if not np.all(np.isfinite(c_values)):
        raise CalibrationError("chassaignac values must be finite")
    bounds = {"min_det_F": float(min_det_F), "sliding_difference": float(max_sliding_difference),
              "nonlinearity": float(linear_threshold)}
    rows = table.assign(chassaignac=c_values).reset_index(drop=True)
    value = rows["value"].astype(float)
    bound = rows["criterion"].map(bounds)
    upper = rows["criterion"].map(lambda k: CRITERIA[k][2] == "<=")
    rows = rows.assign(value=value, bound=bound,
                       passed=np.isfinite(value) & np.where(upper, value <= bound, value >= bound))
    passed, failures = {}, {}
    for c in sorted(set(rows["chassaignac"])):
        mine = rows[rows["chassaignac"] == c]
        passed[c], failures[c] = {}, []
        for criterion in CRITERIA:
            checks = mine[mine["criterion"] == criterion]
            passed[c][criterion] = bool(len(checks)) and bool(checks["passed"].all())
            if not passed[c][criterion]:
                failures[c].append(_failure(criterion, checks, bounds[criterion]))
    chosen = next((c for c in passed if all(passed[c].values())), None)
    return ChassaignacChoice(None if chosen is None else float(chosen), passed, failures, rows)


def _failure(criterion, checks, bound) -> str:
    """One sentence: how many rows of ``criterion`` fail, the worst one and where it is."""
    tag, what, op = CRITERIA[criterion]
    if not len(checks):
        return f"{tag} {what}: no data"
    bad = checks[~checks["passed"]]
    finite = bad[np.isfinite(bad["value"])]
    parts = [f"{tag} {what}: {len(bad)} of {len(checks)} fail"]
    if len(finite):
        worst = finite.loc[finite["value"].idxmin() if op == ">=" else finite["value"].idxmax()]
        negated = "<" if op == ">=" else ">"
        parts.append(f"worst {worst['value']:.3g} {negated} {bound:g} at {worst['where']}")
    missing = bad[~np.isfinite(bad["value"])]
    if len(missing):
        parts.append(f"{len(missing)} without a value (a solve that did not converge), first at "
                     f"{missing.iloc[0]['where']}")
    return "; ".join(parts)

