"""The postures and random initial guesses of a scene, as the job plan writes them into job specs."""

from __future__ import annotations

import numpy as np

from breastcore.model.parameters import IDENTIFIED
from breastcore.model.postures import parse_posture


def _postures(texts):
    return [{"name": p.name, "angle": p.angle} for p in (parse_posture(t) for t in texts)]


def initial_guesses(truth, offset, starts, seed):
    """``starts`` guesses, each parameter drawn uniformly in truth × [1 − offset, 1 + offset].

    ``H`` is redrawn until ``H < R``. Deterministic for a given seed and offset.
    """
    rng = np.random.default_rng([seed, int(round(offset * 1e6))])
    values = np.array([truth[k] for k in IDENTIFIED])
    out = []
    while len(out) < starts:
        guess = values * (1 + rng.uniform(-offset, offset, values.size))
        if guess[1] < guess[0]:
            out.append(dict(zip(IDENTIFIED, (float(v) for v in guess))))
    return out
