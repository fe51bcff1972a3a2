"""The paper's published numbers, for the results page to print beside ours.

Transcribed from Lopes, Clain and Ramires Fernandes (``../shared/paper/``). Rows are
keyed by our mesh level, matched to the paper's by node count ``N``
(:data:`LEVEL_BY_NODES`), since the paper's level names are not consistent: its
Table 1 calls N = 1014 "Medium-Thin", its annex calls it "Thin". Columns are in our
order R, H, λ, μ, λ_s, μ_s (the paper's λ_p, μ_p are our λ_s, μ_s). All values are
percentages unless stated.
"""

from __future__ import annotations

import numpy as np

from breastcore.model.mesh import LEVEL_NODE_COUNTS
from breastcore.model.parameters import IDENTIFIED

#: Our level of each node count (spec §1 takes the paper's six mesh sizes).
LEVEL_BY_NODES = {nodes: level for level, nodes in LEVEL_NODE_COUNTS.items()}


def _rows(table):
    """``{level: {parameter: value}}`` from ``{N: (six values in our order)}``."""
    return {LEVEL_BY_NODES[n]: dict(zip(IDENTIFIED, values)) for n, values in table.items()}


#: Table 1: parameter loss (%) after 25 iterations, mean of 10 tests per mesh; the
#: tests' initial guesses are 10 %, 30 %, 60 % and over 60 % off (not split by offset).
TABLE1 = _rows({226: (0.08, 0.39, 0.42, 0.89, 0.27, 2.77), 572: (0.10, 0.47, 1.39, 0.79, 0.36, 2.40),
                1014: (0.05, 1.20, 1.12, 0.79, 1.16, 2.32), 1404: (0.06, 0.98, 1.07, 0.76, 0.95, 2.28),
                2127: (0.08, 0.68, 0.92, 0.65, 0.85, 2.14), 2498: (0.07, 0.72, 0.97, 0.62, 0.86, 2.13)})

#: Table 2: "mean squared error" (dimensionless) of each mesh's measurements at the
#: reference parameters against the reference mesh's, and the running time relative
#: to the coarse mesh. The paper gives no ultra-thin column.
TABLE2 = {LEVEL_BY_NODES[n]: {"residual": r, "relative_time": t} for n, r, t in (
    (226, 1.52e-3, 1.0), (572, 2.72e-4, 3.4), (1014, 7.26e-5, 7.8), (1404, 3.91e-5, 11.2), (2127, 9.13e-7, 20.0))}

#: Tables 3 and 4: mean and standard deviation over iterations 15-25 of the
#: parameter difference (%) from Λ̄, Gauss-Newton from a guess up to 60 % off.
EVOLUTION_MEAN = _rows({572: (0.35, 6.26, 48.70, 8.71, 2.17, 20.33), 1014: (0.24, 4.30, 30.18, 6.82, 2.19, 14.74),
                        1404: (0.09, 4.25, 17.93, 5.57, 1.64, 14.30), 2127: (0.05, 2.53, 4.21, 2.23, 1.20, 5.35)})
EVOLUTION_SD = _rows({572: (0.27, 1.83, 4.55, 7.22, 5.01, 21.15), 1014: (0.14, 0.64, 3.66, 4.49, 3.53, 12.19),
                      1404: (0.05, 0.31, 2.94, 2.52, 1.68, 7.10), 2127: (0.05, 0.23, 2.89, 1.53, 1.34, 4.01)})

#: Annex, case A (guesses up to 50 % off): mean parameter error (%) of 50 cases,
#: with the mean cycles (iterations) and time (s, Intel i5-2450M) per mesh.
ANNEX_A = _rows({226: (2.30, 2.71, 5.28, 3.07, 9.41, 15.72), 1014: (2.42, 3.78, 5.11, 2.68, 9.24, 15.19),
                 2498: (2.56, 3.83, 5.07, 2.48, 9.13, 14.43)})
ANNEX_A_CYCLES_TIME = {LEVEL_BY_NODES[n]: {"iterations": c, "time_s": t}
                       for n, c, t in ((226, 12, 196.0), (1014, 13, 696.0), (2498, 14, 1587.0))}

#: Annex, case A: mean |M/M̄ − 1| (%) per measurement m1..m15.
#: The paper labels these rows Coarse, Medium and Thin without node counts (its annex
#: names its meshes coarse, thin and ultra-thin, N = 226, 1014, 2498, so Medium and
#: Thin are probably 1014 and 2498); they are keyed by its labels, not matched to ours.
ANNEX_A_MEASUREMENTS = {
    "Coarse": (0.47, 0.64, 0.87, 0.52, 6.53, 0.73, 0.51, 0.80, 0.76, 8.23, 0.67, 0.43, 0.51, 0.56, 7.52),
    "Medium": (0.48, 0.61, 0.82, 0.51, 6.21, 0.67, 0.63, 0.83, 0.75, 7.11, 0.73, 0.52, 0.57, 0.55, 5.87),
    "Thin": (0.48, 0.50, 0.79, 0.51, 6.18, 0.61, 0.51, 0.85, 0.73, 7.17, 0.67, 0.47, 0.52, 0.55, 5.73)}
#: Its printed mean costs (1.99e-6, 1.81e-6, 1.72e-6) are not transcribed: they cannot
#: be the relative cost of the errors above (e5, e10 and e15 alone give Σ (e/100)² ≥ 0.017).

#: Annex, case B (case A plus measurement errors up to 10 %): mean parameter error (%).
ANNEX_B = _rows({226: (8.05, 9.49, 15.31, 6.45, 19.76, 39.3), 1014: (8.47, 13.23, 14.82, 5.63, 19.40, 37.98),
                 2498: (8.96, 13.41, 14.70, 5.21, 19.17, 36.08)})

#: The parameter-error tables a synthetic scene's ``paper_table`` key selects (its Tables
#: 3 and 4 are printed with the ``evolution`` table instead).
PARAMETER_TABLES = {"table1": ("the paper's Table 1", TABLE1), "annex_a": ("the paper's annex, case A", ANNEX_A),
                    "annex_b": ("the paper's annex, case B", ANNEX_B)}

#: The sensitivity table (its very-thin mesh), rows m1..m15, in our column order. The
#: paper prints magnitudes ("all the values are positive") and its columns as R, H,
#: λ, λ_p, μ, μ_p, reordered here.
SENSITIVITY = np.array([
    [0.0016, 0.0113, 0.0478, 0.0058, 0.0272, 0.0021],
    [0.2628, 0.2802, 5.4429, 1.0576, 8.2985, 1.4528],
    [0.0566, 0.5668, 1.5790, 4.3696, 1.2637, 12.3298],
    [0.3232, 0.8874, 17.4148, 3.0257, 5.4678, 10.6005],
    [0.0369, 0.2766, 0.6299, 1.1390, 0.0739, 3.4336],
    [0.0016, 0.0034, 0.0611, 0.0128, 0.0157, 0.0251],
    [0.4995, 0.7457, 7.8666, 5.0323, 7.0629, 18.0483],
    [0.1920, 0.1134, 16.4224, 5.0502, 2.6954, 23.8555],
    [1.0510, 0.2342, 5.2028, 0.1780, 0.8115, 1.2001],
    [0.0038, 0.0317, 0.0846, 0.0549, 0.0025, 0.1724],
    [0.0022, 0.0063, 0.0359, 0.0144, 0.0001, 0.0416],
    [0.0599, 0.6822, 0.7975, 0.5324, 2.5195, 0.4907],
    [0.3179, 1.7219, 5.7136, 2.4447, 0.2099, 7.8664],
    [0.9880, 0.1418, 4.2689, 4.4837, 0.6020, 11.0254],
    [0.0020, 0.0121, 0.1050, 0.0077, 0.0191, 0.0355],
])[:, [0, 1, 2, 4, 3, 5]]
