"""A random admissible deformation, shared by the energy, compiled-kernel and factorisation tests."""

import numpy as np


def deformed(nodes, rng, amplitude=0.15):
    """A random, strongly non-linear but admissible deformation."""
    scale = np.ptp(nodes)
    A = np.eye(3) + 0.3 * rng.standard_normal((3, 3)) / 3
    x = nodes @ A.T + amplitude * scale * rng.uniform(-0.5, 0.5, nodes.shape) / 3
    return x
