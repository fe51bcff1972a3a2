"""Model parameters with units, defaults and their sources.

The six identified parameters are ``Λ = (R, H, λ, μ, λ_s, μ_s)``; the other
constants are fixed by the spec (``shared/spec/model.md``, section 2) because the
paper does not give them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

#: Names of the six identified parameters, in the paper's order.
IDENTIFIED = ("R", "H", "lambda_breast", "mu_breast", "lambda_skin", "mu_skin")


@dataclass(frozen=True)
class ParameterInfo:
    """Metadata of one parameter: unit, long name, default and where it comes from."""

    units: str
    long_name: str
    default: float
    source: str
    cli: str


#: Every parameter of the forward model. Defaults: the paper's reference set Λ̄
#: (section 5) and the spec's constants (section 2).
PARAMETER_INFO = {
    "R": ParameterInfo("m", "sphere radius of the gravity-free cap", 0.0562, "paper §5 (Λ̄)", "--R"),
    "H": ParameterInfo("m", "height of the gravity-free cap", 0.05, "paper §5 (Λ̄)", "--H"),
    "lambda_breast": ParameterInfo("Pa", "bulk first Lamé parameter λ", 1000.0, "paper §5 (Λ̄)", "--lambda-breast"),
    "mu_breast": ParameterInfo("Pa", "bulk shear modulus μ", 150.0, "paper §5 (Λ̄)", "--mu-breast"),
    "lambda_skin": ParameterInfo("Pa", "skin first Lamé parameter λ_s", 8000.0, "paper §5 (Λ̄)", "--lambda-skin"),
    "mu_skin": ParameterInfo("Pa", "skin shear modulus μ_s", 1600.0, "paper §5 (Λ̄)", "--mu-skin"),
    "skin_thickness": ParameterInfo("m", "skin thickness t_s (membrane stiffness = modulus × t_s)", 1e-3, "spec §2", "--skin-thickness"),
    "density": ParameterInfo("kg m-3", "bulk density ρ", 1000.0, "spec §2", "--density"),
    "gravity_magnitude": ParameterInfo("m s-2", "gravitational acceleration g", 9.81, "spec §2", "--gravity"),
    "chassaignac": ParameterInfo("Pa", "Chassaignac sliding coefficient c", 500.0,
                                 "calibration (config/calibration.yaml; spec §2)", "--chassaignac"),
    "smoothing": ParameterInfo("m", "Chassaignac smoothing length δ", 1e-6, "spec §2", "--smoothing"),
    "fold_angle": ParameterInfo("degree", "arc angle θ_D of the fixed infra-mammary fold", 180.0, "spec §1", "--fold-angle"),
}


#: Parameters that must be > 0 and those that must be >= 0 (0 switches a term off);
#: ``fold_angle`` lies in ``(FOLD_ANGLE_RANGE[0], FOLD_ANGLE_RANGE[1]]`` degrees. The command
#: line checks its options against the same ranges (``breastcore.cli.options.parameter_type``).
POSITIVE_PARAMETERS = ("R", "H", "mu_breast", "smoothing", "density")
NON_NEGATIVE_PARAMETERS = ("lambda_breast", "lambda_skin", "mu_skin", "skin_thickness", "chassaignac",
                           "gravity_magnitude")
FOLD_ANGLE_RANGE = (0.0, 360.0)


class ParameterError(ValueError):
    """A parameter value that the model cannot use (names the parameter)."""


def _default(name: str):
    return field(default=PARAMETER_INFO[name].default)


@dataclass(frozen=True)
class Parameters:
    """All inputs of one forward solve, in SI units (``fold_angle`` in degrees).

    Raises
    ------
    ParameterError
        If a value is non-finite, a modulus is negative, ``H >= R`` or a
        length is not positive. The message names the offending parameter.
    """

    R: float = _default("R")
    H: float = _default("H")
    lambda_breast: float = _default("lambda_breast")
    mu_breast: float = _default("mu_breast")
    lambda_skin: float = _default("lambda_skin")
    mu_skin: float = _default("mu_skin")
    skin_thickness: float = _default("skin_thickness")
    density: float = _default("density")
    gravity_magnitude: float = _default("gravity_magnitude")
    chassaignac: float = _default("chassaignac")
    smoothing: float = _default("smoothing")
    fold_angle: float = _default("fold_angle")

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"{f.name} must be a number, got {value!r}") from None
            if not math.isfinite(value):
                raise ParameterError(f"{f.name} must be finite, got {value}")
            object.__setattr__(self, f.name, value)
        for name in POSITIVE_PARAMETERS:
            if getattr(self, name) <= 0:
                raise ParameterError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in NON_NEGATIVE_PARAMETERS:
            if getattr(self, name) < 0:
                raise ParameterError(f"{name} must be >= 0, got {getattr(self, name)}")
        if not self.H < self.R:
            raise ParameterError(f"H must be < R (got H={self.H} m, R={self.R} m)")
        if not FOLD_ANGLE_RANGE[0] < self.fold_angle <= FOLD_ANGLE_RANGE[1]:
            raise ParameterError(f"fold_angle must be in (0, 360] degrees, got {self.fold_angle}")

    def replace(self, **changes) -> "Parameters":
        """Return a copy with some values changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def identified(self) -> tuple[float, ...]:
        """The six identified parameters Λ in the paper's order."""
        return tuple(getattr(self, name) for name in IDENTIFIED)

    def with_identified(self, values) -> "Parameters":
        """Copy with Λ replaced by ``values`` (paper order)."""
        return self.replace(**dict(zip(IDENTIFIED, (float(v) for v in values))))

    def as_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)
