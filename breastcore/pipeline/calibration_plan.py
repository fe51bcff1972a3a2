"""The jobs of a calibration scene of the Chassaignac coefficient c (issue #18).

Jobs per value of c (:func:`plan_calibration`): one ``calibrate`` job per level (cold
solves of every posture at the truth and every box corner), one ``uniqueness`` job
(the probe at the truth), and the truth solve, its measurements and the cross-mesh
identifications, which are the plan's ordinary solve, measure and identify jobs with
the scene's c: other scenes with the same c, truth, seed and options share them.

Imported by the Snakefile (through :mod:`breastcore.pipeline.plan`): it imports
nothing heavy.
"""

from __future__ import annotations

import itertools

from breastcore.model.parameters import IDENTIFIED

#: Short names of the parameters in point labels.
SHORT = {"R": "R", "H": "H", "lambda_breast": "λ", "mu_breast": "μ", "lambda_skin": "λ_s", "mu_skin": "μ_s"}
#: The report figure of the scene (beside its summary).
FIGURE = "table2_residual.png"


def box_points(truth, parameters, factors):
    """The truth, then every corner of the box ``truth[p] × factors`` over ``parameters``.

    Parameters
    ----------
    truth : dict
        The six identified parameters (SI).
    parameters : sequence of str
        The parameters the box spans (the others stay at the truth).
    factors : sequence of float
        The values each of them takes, relative to the truth.

    Returns
    -------
    list of dict
        ``{"label", "parameters"}``: ``"truth"`` first, then the
        ``len(factors) ** len(parameters)`` corners in ``itertools.product`` order,
        labelled like ``R×0.7 H×1.3 λ×0.7 μ×1.3``. A corner may be inadmissible
        (``H ≥ R``); the calibrate job records it so, without a solve.
    """
    truth = {k: float(truth[k]) for k in IDENTIFIED}
    points = [{"label": "truth", "parameters": truth}]
    for combo in itertools.product([float(f) for f in factors], repeat=len(parameters)):
        values = dict(truth)
        for name, factor in zip(parameters, combo):
            values[name] = truth[name] * factor
        points.append({"label": " ".join(f"{SHORT[n]}×{f:g}" for n, f in zip(parameters, combo)), "parameters": values})
    return points


def plan_calibration(plan, scene) -> dict:
    """The scene spec of a validated calibration scene, its jobs registered in ``plan``.

    Parameters
    ----------
    plan : breastcore.pipeline.plan.Plan
    scene : dict
        The scene's config with its defaults filled in.

    Returns
    -------
    dict
        ``cases`` (one per c, ascending: its ``calibrate`` dataset per level, its
        ``uniqueness`` dataset, its truth solution and identification ``runs``),
        ``points`` and what the summary needs to read them (levels, criteria).
    """
    from breastcore.pipeline.starts import _postures, initial_guesses

    postures = _postures(scene["postures"])
    truth = {k: float(scene["truth"][k]) for k in IDENTIFIED}
    points = box_points(truth, scene["box_parameters"], scene["box_factors"])
    levels = [*scene["levels"], scene["reference"]]
    measurement_set = scene["measurement_set"]
    guesses = initial_guesses(truth, scene["offset"], scene["starts"], scene["seed"])
    cases = []
    for c in sorted(float(c) for c in scene["grid"]):
        constants = {**plan.constants, "chassaignac": c}           # the plan's constants, c replaced
        common = {"constants": constants, "solver": plan.solver, "postures": postures,
                  "measurement_set": measurement_set}
        jobs = {level: plan._add("calibrate", {"mesh": plan.mesh(level), "level": level, "points": points, **common},
                                 label=f"{level}-c{c:g}")
                for level in levels}
        probe = plan._add("uniqueness", {"mesh": plan.mesh(scene["probe_level"]), "level": scene["probe_level"],
                                         "truth": truth, "epsilon": scene["probe_epsilon"], **common},
                          label=f"{scene['probe_level']}-c{c:g}")
        # The synthetic scene's own jobs, so that a scene with the same c, truth, seed and
        # options shares them (the paper's Table 1 at c = the constants' c).
        truth_solution, runs = None, []
        if scene["identify_meshes"]:
            truth_solution = plan.solve(plan.mesh(scene["truth_mesh"], truth["R"], truth["H"]), truth, postures,
                                        constants=constants)
            measured = plan._add("measure", {"solution": truth_solution, "measurement_set": measurement_set,
                                             "noise": 0.0, "seed": scene["seed"]}, label=plan.level_of(truth_solution))
            runs = [{"mesh": level, "start": i,
                     "identification": plan.identify(measured, level, guess, scene["identification"],
                                                     constants=constants)}
                    for level in scene["identify_meshes"] for i, guess in enumerate(guesses)]
        cases.append({"chassaignac": c, "levels": jobs, "uniqueness": probe, "truth": truth_solution, "runs": runs})
    return {"cases": cases, "points": points, "truth": truth, "constants": plan.constants,
            "levels": list(scene["levels"]), "reference": scene["reference"], "compare_level": scene["compare_level"],
            "jacobian_level": scene["jacobian_level"], "probe_level": scene["probe_level"],
            "det_F_posture": scene["det_F_posture"], "identify_meshes": list(scene["identify_meshes"]),
            "starts": scene["starts"], "offset": scene["offset"], "box_parameters": list(scene["box_parameters"]),
            "box_factors": list(scene["box_factors"]), "epsilon": scene["probe_epsilon"],
            "criteria": {"min_det_F": scene["min_det_F"], "max_sliding_difference": scene["max_sliding_difference"],
                         "linear_threshold": scene["linear_threshold"]}}


def calibration_inputs(spec) -> list:
    """The datasets the scene summary reads."""
    return [path for case in spec["cases"]
            for path in (*case["levels"].values(), case["uniqueness"], *(r["identification"] for r in case["runs"]))]


def calibration_figures(folder) -> list:
    """The report files of a calibration scene."""
    return [f"{folder}/{FIGURE}"]
