"""Tissue behind the torso plane: the chest-wall contact that the model leaves out.

Spec §2 keeps the back face Γ_B in the torso plane ``y = 0`` and fixes the fold; no
other node is held in front of that plane, since the paper models no contact with
the chest wall. Under gravity the tissue just above a fixed fold can turn over it
and pass behind the plane. The depth it reaches is recorded with every solve, and a
depth above :data:`PENETRATION_LIMIT` is flagged: that shape crosses the chest wall,
so it is outside what the model can represent.
"""

from __future__ import annotations

import numpy as np

from breastcore.model.stability import postures_over

#: Depth behind the torso plane above which a shape is flagged, m. One millimetre: the
#: resolution at which the tape and ruler measurements are read.
PENETRATION_LIMIT = 1e-3


def torso_penetration(position) -> float:
    r"""The largest depth of a node behind the torso plane, m (0 when none is behind it).

    Parameters
    ----------
    position : array_like, shape (N, 3)
        Node positions in the torso frame (y anterior), m.

    Returns
    -------
    float
        :math:`\max(0, -\min_i y_i)`; NaN if a position is not finite. Nodes only: a
        tetrahedron whose nodes are all in front of the plane lies in front of it too, as
        the half-space is convex.
    """
    y = np.asarray(position, dtype=float)[:, 1]
    if not np.all(np.isfinite(y)):
        return float("nan")
    depth = -float(y.min())
    return depth if depth > 0.0 else 0.0                  # +0.0, not the -0.0 of a node on the plane


def penetration_warning(depths) -> str:
    """A one-line warning when a posture's depth exceeds :data:`PENETRATION_LIMIT`, else ``""``.

    Parameters
    ----------
    depths : mapping of str to float
        Posture name to :func:`torso_penetration` of its shape, m. A NaN depth (a
        non-finite shape, which no converged solve returns) is warned too.
    """
    listed = postures_over(depths, PENETRATION_LIMIT, lambda d: f"{d * 1e3:.3g} mm")
    if not listed:
        return ""
    return (f"tissue behind the torso plane y = 0 by more than {PENETRATION_LIMIT * 1e3:g} mm ({listed}): "
            "the shape crosses the chest wall, whose contact the model leaves out")
