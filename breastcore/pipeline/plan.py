"""The job plan of the workflow: which datasets each scene needs, keyed by their inputs.

Every job is defined by a small JSON-able spec; its output path carries a short hash
of that spec, so two scenes that need the same mesh, solve or identification share
one file, and a changed spec gives a new path (and only its own jobs rerun).

Paths (under ``results/``)::

    mesh/{level}.nc                         fixed-topology level mesh at the paper's (R, H)
    mesh/{level}-direct-{key}.nc            gmsh directly at a true (R, H) (synthetic truth)
    solve/{key}.nc                          solution dataset
    measure/{key}.nc                        measurement dataset (synthetic or patient)
    identify/{key}.nc                       identification dataset
    sensitivity/{key}.nc                    sensitivity dataset
    stability/{key}.nc                      one chunk of a stability scene's grid
    extreme/{key}.nc                        identifications from extreme guesses on one level
    calibrate/{key}.nc                      a calibration scene's cold solves on one level, for one c
    uniqueness/{key}.nc                     a calibration scene's uniqueness probe, for one c
    scenes/{scene}/summary.nc               the scene's summary; attrs["datasets"] lists the above it uses
    scenes/{scene}/...                      per-scene tables and figures (report)
"""

from __future__ import annotations


from breastcore.pipeline.keys import spec_key
from breastcore.pipeline.starts import _postures, initial_guesses


class Plan:
    """All jobs of a validated config. ``targets(scene)`` lists what a scene needs."""

    def __init__(self, config):
        self.results = config["results"].rstrip("/")
        self.constants = config["constants"]
        self.solver = config["solver"]
        self.report = config["report"]["enabled"]
        self.run_scenes = config.get("run_scenes") or list(config["scenes"])
        self.max_starts = config.get("max_starts")
        self.identify_batch = config["identify_batch"]
        self.jobs = {"mesh": {}, "solve": {}, "measure": {}, "identify": {}, "sensitivity": {}, "stability": {}, "extreme": {},
                     "calibrate": {}, "uniqueness": {}, "scene": {}}
        self.scenes = {}
        for name, scene in config["scenes"].items():
            self.scenes[name] = getattr(self, f"_{scene['kind']}")(name, scene)

    # -- job registration -------------------------------------------------------------
    def _add(self, stage, spec, path=None, label=None):
        """Register a job; its file is ``<stage>/<label>-<key>.nc``, the key a hash of its spec.

        The label (a mesh level, a method, ``patient``) is there for whoever browses
        ``results/``; the key alone identifies the job.
        """
        if path is None:
            name = spec_key(spec) if label is None else f"{label}-{spec_key(spec)}"
            path = f"{self.results}/{stage}/{name}.nc"
        self.jobs[stage][path] = spec
        return path

    def level_of(self, path):
        """The mesh level behind a job's output path (None: a patient's measurements, or not a job)."""
        spec = next((jobs[path] for jobs in self.jobs.values() if path in jobs), None)
        if spec is None:
            return None
        if "level" in spec:
            return spec["level"]
        upstream = spec.get("mesh") or spec.get("solution") or spec.get("identification")
        return self.level_of(upstream) if upstream else None

    def mesh(self, level, R=None, H=None):
        if R is None:
            return self._add("mesh", {"level": level}, f"{self.results}/mesh/{level}.nc")
        spec = {"level": level, "R": R, "H": H, "fold_angle": self.constants["fold_angle"]}
        return self._add("mesh", spec, f"{self.results}/mesh/{level}-direct-{spec_key(spec)}.nc")

    def solve(self, mesh_path, parameters, postures, constants=None):
        """``constants``: a scene's own, in place of the config's (the calibration scene's c)."""
        spec = {"mesh": mesh_path, "parameters": {**(constants or self.constants), **parameters},
                "postures": postures, "solver": self.solver}
        return self._add("solve", spec, label=self.level_of(mesh_path))

    def identify(self, measure_path, level, initial, identification, solver=None, constants=None):
        spec = {"measurements": measure_path, "mesh": self.mesh(level), "initial": initial,
                "constants": constants or self.constants, "solver": solver or self.solver,
                "identification": identification}
        return self._add("identify", spec, label=f"{level}-{identification.get('method', 'lm')}")

    def sensitivity(self, identify_path, mode):
        label = f"{self.level_of(identify_path) or 'patient'}-{'finite' if mode == 'both' else 'linear'}"
        return self._add("sensitivity", {"identification": identify_path, "finite": mode == "both", "delta": 0.1},
                         label=label)

    # -- scenes -----------------------------------------------------------------------
    def _synthetic(self, name, scene):
        postures = _postures(scene["postures"])

        def truth_on(mesh_path):
            solution = self.solve(mesh_path, scene["truth"], postures)
            return solution, self._add("measure", {"solution": solution, "measurement_set": scene["measurement_set"],
                                                   "noise": scene["noise"], "seed": scene["seed"]},
                                       label=self.level_of(solution))

        # truth_mesh "same": each level identifies data solved on itself (the paper's Table 1
        # layout, an inverse crime); otherwise on a level that gmsh meshes at the true (R, H)
        same = scene["truth_mesh"] == "same"
        if not same:
            truth, measured = truth_on(self.mesh(scene["truth_mesh"], scene["truth"]["R"], scene["truth"]["H"]))
        levels_run = dict.fromkeys(level for m in scene["methods"] for level in m.get("meshes", scene["meshes"]))
        truths = {level: truth_on(self.mesh(level)) for level in levels_run} if same else {}
        if same:
            truth = next(iter(truths.values()))[0]
        runs = []
        for m in scene["methods"]:
            ident = {**scene["identification"], "method": m.get("method", "lm"),
                     "jacobian": m.get("jacobian", "implicit"), "max_iterations": m.get("max_iterations", scene["identification"]["max_iterations"])}
            solver = {**self.solver, "method": m.get("solver", "newton")}
            for level in m.get("meshes", scene["meshes"]):
                for offset in scene["offsets"]:
                    guesses = initial_guesses(scene["truth"], offset, scene["starts"], scene["seed"])
                    guesses = guesses[:self.max_starts] if self.max_starts else guesses
                    for i, guess in enumerate(guesses):
                        path = self.identify(truths[level][1] if same else measured, level, guess, ident, solver)
                        runs.append({"method": m["name"], "mesh": level, "offset": offset, "start": i,
                                     "identification": path})
        sens = [self.sensitivity(r["identification"], scene["sensitivity"]) for r in runs[:1]
                if scene["sensitivity"] != "none"]
        tables = list(scene.get("tables", []))
        # The paper's Table 2 residual: each level solved at the truth, no identification.
        levels = dict.fromkeys(r["mesh"] for r in runs) if "levels" in tables else {}
        level_solutions = {level: self.solve(self.mesh(level), scene["truth"], postures) for level in levels}
        return self._scene(name, "synthetic", {"runs": runs, "truth": truth, "sensitivity": sens, "tables": tables,
                                               "paper_table": scene.get("paper_table", "none"),
                                               "level_solutions": level_solutions, "truth_mesh": scene["truth_mesh"]})

    def _patient(self, name, scene):
        postures = {k: dict(v) for k, v in scene["postures"].items()}
        spec = {"patient": {"postures": postures, "units": scene["units"],
                            "measurement_set": scene["measurement_set"]}}
        if scene["allow_implausible"]:                   # only then: the usual spec (and its path) is unchanged
            spec["patient"]["allow_implausible"] = True
        measured = self._add("measure", spec, label="patient")
        ident = self.identify(measured, scene["mesh"], scene["initial"], scene["identification"])
        sens = [self.sensitivity(ident, scene["sensitivity"])] if scene["sensitivity"] != "none" else []
        names = list(postures)
        return self._scene(name, "patient", {"identification": ident, "sensitivity": sens, "postures": names})

    def _forward(self, name, scene):
        postures = _postures(scene["postures"])
        solution = self.solve(self.mesh(scene["mesh"]), scene["parameters"], postures)
        return self._scene(name, "forward", {"solution": solution, "postures": [p["name"] for p in postures]})

    def _stability(self, name, scene):
        from breastcore.studies.stability import grid_cases
        chunks = []
        for level in scene["meshes"]:
            cases = grid_cases(scene["grid"], scene["sample"], scene["seed"])
            for i in range(scene["chunks"]):
                part = cases[i::scene["chunks"]]
                if part:
                    chunks.append(self._add("stability", {"mesh": self.mesh(level), "level": level, "cases": part,
                                                          "constants": self.constants, "solver": self.solver},
                                            label=level))
        guesses = [self._add("extreme", {"mesh": self.mesh(level), "level": level, "factors": scene["extreme_guesses"],
                                         "identification": scene["identification"], "constants": self.constants,
                                         "solver": self.solver}, label=level)
                   for level in scene["meshes"] if scene["extreme_guesses"]]
        return self._scene(name, "stability", {"chunks": chunks, "guesses": guesses})

    def _calibration(self, name, scene):
        from breastcore.pipeline.calibration_plan import plan_calibration
        return self._scene(name, "calibration", plan_calibration(self, scene))

    def _scene(self, name, kind, spec):
        spec = {"kind": kind, **spec}
        folder = f"{self.results}/scenes/{name}"
        summary = f"{folder}/summary.nc"
        self.jobs["scene"][summary] = spec
        return {"summary": summary, "figures": self.figures(name, spec) if self.report else [], **spec}

    def figures(self, name, spec):
        """Report files of a scene (PNG pictures, and tables as CSV with their HTML page)."""
        folder = f"{self.results}/scenes/{name}"
        if spec["kind"] == "stability":
            return [f"{folder}/stability_map.png", f"{folder}/stability.csv", f"{folder}/stability.html"]
        if spec["kind"] == "calibration":
            from breastcore.pipeline.calibration_plan import calibration_figures
            return calibration_figures(folder)
        if spec["kind"] == "synthetic":
            out = [f"{folder}/convergence.png", f"{folder}/parameter_errors.csv", f"{folder}/parameter_errors.html",
                   f"{folder}/error_vs_runtime.png"]
        else:
            out = [f"{folder}/shape_{p}.{ext}" for p in spec["postures"] for ext in ("png", "vtu")]
            out += [f"{folder}/diagnostics.csv", f"{folder}/diagnostics.html"]
            if spec["kind"] == "patient":
                out += [f"{folder}/convergence.png", f"{folder}/parameters.csv", f"{folder}/parameters.html"]
        if spec.get("sensitivity"):
            out.append(f"{folder}/sensitivity.png")
        return out

    def scene(self, name):
        return self.jobs["scene"][f"{self.results}/scenes/{name}/summary.nc"]

    def scene_inputs(self, summary_path):
        """Datasets a scene summary reads."""
        spec = self.jobs["scene"][summary_path]
        if spec["kind"] == "synthetic":
            return ([r["identification"] for r in spec["runs"]] + spec["sensitivity"] + [spec["truth"]]
                    + list(spec.get("level_solutions", {}).values()))
        if spec["kind"] == "patient":
            return [spec["identification"], *spec["sensitivity"]]
        if spec["kind"] == "stability":
            return spec["chunks"] + spec.get("guesses", [])
        if spec["kind"] == "calibration":
            from breastcore.pipeline.calibration_plan import calibration_inputs
            return calibration_inputs(spec)
        return [spec["solution"]]

    def scene_datasets(self, name):
        """Every stage dataset scene ``name`` is computed from, in first-use order, as paths
        relative to the results folder (``mesh/coarse.nc``, ``identify/<key>.nc``, ...).

        Found by following the paths that the job specs name, from the scene's own spec
        down to its meshes; shared files appear in every scene that uses them.
        """
        producers = {path: spec for stage, jobs in self.jobs.items() if stage != "scene"
                     for path, spec in jobs.items()}
        found = {}

        def visit(value):
            if isinstance(value, str):
                if value in producers and value not in found:
                    found[value] = None
                    visit(producers[value])
            elif isinstance(value, dict):
                for item in value.values():
                    visit(item)
            elif isinstance(value, (list, tuple)):
                for item in value:
                    visit(item)

        visit(self.scene(name))
        return [path[len(self.results) + 1:] for path in found]

    def shape_source(self, name):
        """The dataset whose shapes a patient or forward scene shows."""
        spec = self.scene(name)
        return spec["identification"] if spec["kind"] == "patient" else spec["solution"]

    def front_page_scenes(self):
        """``(name, summary, PNG figures)`` of each scene in ``run_scenes``, for the report's first page."""
        return [(name, self.scenes[name]["summary"], [f for f in self.scenes[name]["figures"] if f.endswith(".png")])
                for name in self.run_scenes]

    def all_targets(self):
        """Outputs of the scenes in ``run_scenes`` (all scenes if it is empty), and the report's
        first page when the report is enabled."""
        out = []
        for name in self.run_scenes:
            out += [self.scenes[name]["summary"], *self.scenes[name]["figures"]]
        return out + ([f"{self.results}/report/front.html"] if self.report and self.run_scenes else [])


def plan_from_files(*paths, schema=None) -> Plan:
    """The plan of ``config.yaml``-style files, each one's top-level keys over the files before it.

    For the scripts that read a run's jobs (``breastcore.studies.compare_runs --paper-only``):
    ``plan_from_files("config.yaml", "config/paper.yaml")``. Unlike Snakemake's
    ``--configfile``, a later file replaces a whole top-level key (``scenes`` too).
    """
    from pathlib import Path

    import yaml

    from breastcore.pipeline.config import DEFAULT_SCHEMA, validate_config
    config = {}
    for path in paths:
        config.update(yaml.safe_load(Path(path).read_text()))
    return Plan(validate_config(config, str(schema or DEFAULT_SCHEMA)))
