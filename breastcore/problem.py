"""One problem definition carried through every stage: model, solver, postures, measurements, identification.

A :class:`ProblemSpec` is written into each stage dataset (attribute ``problem``,
JSON) and every later stage rebuilds its model from it, so nothing downstream falls
back to a default that the upstream stage did not use: the finite sensitivity of an
identification re-identifies with exactly its constants, solver and options.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from typing import TYPE_CHECKING

from breastcore.forward.options import SolverOptions
from breastcore.inverse.options import IdentificationOptions
from breastcore.model.parameters import Parameters
from breastcore.model.postures import Posture, paper_postures

if TYPE_CHECKING:                      # numba and PARDISO load with it: a spec is read without them
    from breastcore.forward.model import ForwardModel

#: Name of the dataset attribute that holds the JSON of the spec.
ATTRIBUTE = "problem"


class ProblemSpecError(ValueError):
    """A dataset without a readable problem spec, or a spec with unknown or missing fields."""


@dataclass(frozen=True)
class ProblemSpec:
    """Everything that defines ``Λ ↦ M(Λ)`` and its identification, apart from the mesh.

    Attributes
    ----------
    parameters : Parameters
        Λ and the constants (ρ, g, c, δ, t_s, θ_D). In an identification, Λ is the
        initial guess; the estimate is stored apart.
    solver : SolverOptions
    postures : tuple of Posture
    measurement_set : {"paper15", "exact"} or None
        None where no measurement is taken (a solve).
    identification : IdentificationOptions or None
        None where nothing is identified (a solve, synthetic measurements).
    """

    parameters: Parameters = Parameters()
    solver: SolverOptions = SolverOptions()
    postures: tuple = paper_postures()
    measurement_set: str | None = None
    identification: IdentificationOptions | None = None

    def __post_init__(self):
        object.__setattr__(self, "postures", tuple(self.postures))

    def replace(self, **changes) -> "ProblemSpec":
        return dataclasses.replace(self, **changes)

    # -- models ---------------------------------------------------------------------------
    def forward_model(self, mesh) -> ForwardModel:
        """The forward model on ``mesh`` with this spec's solver options.

        ``Λ ↦ M(Λ)`` is :meth:`breastcore.inverse.operator.MeasurementModel.from_problem`.
        """
        from breastcore.forward.model import ForwardModel
        return ForwardModel(mesh, self.solver)

    def warm_radius(self) -> float:
        """The warm-start radius of the identification options.

        Raises ProblemSpecError for a spec without identification options (a solve, a
        measurement, a calibration): it defines no radius, and none is made up.
        """
        if self.identification is None:
            raise ProblemSpecError("this problem spec has no identification options, hence no warm-start radius "
                                   "(warm_radius): only an identification problem defines one")
        return self.identification.warm_radius

    def check_model(self, mm) -> None:
        """Raise ProblemSpecError unless the measurement model ``mm`` is the one this spec builds.

        A dataset that records this spec must have been computed with it: constants,
        solver options, postures, measurement set, warm-start radius, reduced-start snapshots and tangent starts. The spec must
        have identification options (the radius is theirs; ProblemSpecError otherwise).
        """
        radius = self.warm_radius()
        found = {"parameters": mm.base, "solver": mm.model.options, "postures": tuple(mm.postures),
                 "measurement_set": mm.measurement_set, "warm_radius": mm.warm_radius,
                 "reduced_snapshots": mm.reduced_snapshots, "tangent_starts": mm.tangent_starts}
        wanted = {"parameters": self.parameters, "solver": self.solver, "postures": self.postures,
                  "measurement_set": self.measurement_set, "warm_radius": radius,
                  "reduced_snapshots": self.identification.reduced_snapshots,
                  "tangent_starts": self.identification.tangent_starts}
        wrong = [k for k in wanted if found[k] != wanted[k]]
        if wrong:
            raise ProblemSpecError(f"the measurement model differs from the problem spec in {', '.join(wrong)}")

    # -- serialisation --------------------------------------------------------------------
    def as_dict(self) -> dict:
        return {
            "parameters": self.parameters.as_dict(),
            "solver": dataclasses.asdict(self.solver),
            "postures": [{"name": p.name, "angle": p.angle} for p in self.postures],
            "measurement_set": self.measurement_set,
            "identification": None if self.identification is None else dataclasses.asdict(self.identification),
        }

    def to_json(self) -> str:
        return json.dumps(self.as_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, data) -> "ProblemSpec":
        """Inverse of :meth:`as_dict`; unknown or missing fields are refused, never defaulted."""
        fields = {f.name for f in dataclasses.fields(cls)}
        if set(data) != fields:
            raise ProblemSpecError(f"problem spec fields {sorted(data)}; expected {sorted(fields)}")
        try:
            ident = data["identification"]
            return cls(parameters=Parameters(**_exact(Parameters, data["parameters"])),
                       solver=SolverOptions(**_exact(SolverOptions, data["solver"])),
                       postures=tuple(Posture(p["name"], float(p["angle"])) for p in data["postures"]),
                       measurement_set=data["measurement_set"],
                       identification=None if ident is None else
                       IdentificationOptions(**_exact(IdentificationOptions, ident)))
        except (TypeError, KeyError, ValueError) as err:
            raise ProblemSpecError(f"invalid problem spec: {err}") from None

    @classmethod
    def from_json(cls, text) -> "ProblemSpec":
        try:
            data = json.loads(text)
        except ValueError as err:
            raise ProblemSpecError(f"problem spec is not JSON: {err}") from None
        return cls.from_dict(data)

    def attrs(self) -> dict:
        """The dataset attribute that stores this spec."""
        return {ATTRIBUTE: self.to_json()}

    @classmethod
    def from_dataset(cls, ds) -> "ProblemSpec":
        """The spec a stage dataset was computed with. Raises ProblemSpecError if it has none."""
        if ATTRIBUTE not in ds.attrs:
            raise ProblemSpecError(f"dataset of stage {ds.attrs.get('stage', '?')!r} carries no problem spec "
                                   f"(attribute {ATTRIBUTE!r}); it was written by another breastcore version: "
                                   f"recompute it")
        return cls.from_json(ds.attrs[ATTRIBUTE])


#: Fields added to a spec dataclass after datasets were written without them, with the value
#: that reproduces what those datasets were computed with (not a default: the method of then).
#: ``reuse_factor`` 0: a fresh factorisation every Newton iteration, the only method before issue #21.
#: ``sliding_dual``, ``inertia_shift`` False: exact-Hessian steps and the PSD projection, the method before them.
#: ``mixed_precision_min_dofs`` 100000: the module threshold of then.
#: ``step_rtol`` 1e-10, ``skip_futile_shifts`` False: every Newton direction refined to 1e-10, and the
#: inertia shifts tried at every indefinite step.
#: ``sliding_release`` False: the primal-dual sliding steps without released nodes.
#: ``deep_indefinite_skips`` 0: an exact factorisation at every fresh Newton step.
#: ``tangent_starts`` False: solves after a Jacobian started from the plain warm or the reduced start.
ADDED_FIELDS = {"SolverOptions": {"reuse_factor": 0.0, "sliding_dual": False, "inertia_shift": False,
                                  "mixed_precision_min_dofs": 100_000, "step_rtol": 1e-10,
                                  "skip_futile_shifts": False, "sliding_release": False,
                                  "deep_indefinite_skips": 0},
                "IdentificationOptions": {"tangent_starts": False}}


def _exact(kind, values) -> dict:
    """``values`` if its keys are exactly the fields of the dataclass ``kind`` (those of
    :data:`ADDED_FIELDS` may be missing: they take their historical value), else ProblemSpecError."""
    names = {f.name for f in dataclasses.fields(kind)}
    values = {**{k: v for k, v in ADDED_FIELDS.get(kind.__name__, {}).items() if k not in values}, **values}
    if set(values) != names:
        missing, unknown = sorted(names - set(values)), sorted(set(values) - names)
        raise ProblemSpecError(f"{kind.__name__} in the problem spec: missing {missing}, unknown {unknown}")
    return dict(values)
