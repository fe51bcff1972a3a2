"""Postures: a forward-bend angle θ and its gravity vector in the torso frame."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

#: The paper's three postures and their forward-bend angles, degrees (spec §3).
PAPER_POSTURES = {"standing": 0.0, "bent45": 45.0, "fours": 90.0}


class PostureError(ValueError):
    """An unknown posture name or an angle outside [0°, 90°]."""


@dataclass(frozen=True)
class Posture:
    """A named posture with forward-bend angle ``angle`` in degrees, 0 ≤ θ ≤ 90.

    A paper posture's name keeps its own angle: ``Posture("standing", 45)`` is refused,
    since data labelled standing would otherwise be solved bent forward.
    """

    name: str
    angle: float

    def __post_init__(self):
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_\-]*", self.name):
            raise PostureError(f"posture name {self.name!r} must be an identifier (letters, digits, _ or -)")
        if not (math.isfinite(self.angle) and 0.0 <= self.angle <= 90.0):
            raise PostureError(f"posture {self.name!r}: angle must be in [0, 90] degrees, got {self.angle}")
        if self.name in PAPER_POSTURES and self.angle != PAPER_POSTURES[self.name]:
            raise PostureError(f"posture {self.name!r} is the paper's posture at {PAPER_POSTURES[self.name]:g} "
                               f"degrees; give another name for {self.angle:g} degrees")

    def gravity(self, g=9.81):
        """``a_g = g (0, sin θ, −cos θ)`` in m s⁻² (spec §3)."""
        theta = math.radians(self.angle)
        return g * np.array([0.0, math.sin(theta), -math.cos(theta)])


def parse_posture(text: str) -> Posture:
    """``"NAME"`` (one of the paper's) or ``"NAME=ANGLE"`` (degrees)."""
    if "=" in text:
        name, _, angle = text.partition("=")
        name = name.strip()
        try:
            value = float(angle)
        except ValueError:
            raise PostureError(f"posture {text!r}: angle {angle!r} is not a number") from None
        return Posture(name, value)
    if text not in PAPER_POSTURES:
        raise PostureError(f"unknown posture {text!r}; known: {', '.join(PAPER_POSTURES)} (or NAME=ANGLE)")
    return Posture(text, PAPER_POSTURES[text])


def paper_postures() -> tuple[Posture, ...]:
    return tuple(Posture(n, a) for n, a in PAPER_POSTURES.items())
