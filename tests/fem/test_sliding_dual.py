"""The primal-dual sliding blocks: the exact Hessian at ``q = u/r``, a first-order dual update, and
positive definiteness for every admissible ``q``."""

import numpy as np

from breastcore.fem.loads import Chassaignac
from breastcore.fem.sliding_dual import SlidingDual


def back_plane(n=4, delta=1e-3):
    """A flat back of ``n × n`` nodes in the plane y = 0 and its Chassaignac term (c = 100 Pa)."""
    s = np.linspace(0.0, 0.03, n)
    X, Z = np.meshgrid(s, s, indexing="ij")
    nodes = np.column_stack([X.ravel(), np.zeros(X.size), Z.ravel()])
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel()
    triangles = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    return nodes, Chassaignac(nodes, triangles, coefficient=100.0, smoothing=delta)


def slid(nodes, scale, seed=0):
    """Nodes moved by slips of random direction and size ~``scale`` (m), some below δ, some above."""
    rng = np.random.default_rng(seed)
    x = nodes.copy()
    x[:, [0, 2]] += scale * rng.standard_normal((len(nodes), 2)) * rng.uniform(0.01, 3.0, (len(nodes), 1))
    return x


def test_fresh_dual_blocks_are_the_exact_hessian():
    nodes, term = back_plane()
    x = slid(nodes, 1e-3)
    dual = SlidingDual(term)
    np.testing.assert_allclose(dual.element_hessians(x), term.element_hessians(x), rtol=1e-12, atol=0)
    assert np.allclose(np.linalg.norm(dual.q, axis=1), np.linalg.norm(term.gradient(x)[term.connectivity[:, 0]],
                                                                      axis=1) / term.weight)   # q = u/r = force / w


def test_dual_update_is_the_first_order_value_of_u_over_r():
    """From ``q = u/r``, the update to ``u + h Δu`` is ``u'/r'`` to O(h²): the error falls 4× per halving."""
    nodes, term = back_plane(delta=1e-3)
    x0 = slid(nodes, 3e-3, seed=1)
    direction = slid(nodes, 1e-3, seed=2) - nodes
    errors = []
    for h in (0.2, 0.1, 0.05):
        dual = SlidingDual(term)
        dual.update(x0)
        x1 = x0 + h * direction
        dual.update(x1)
        u1 = x1[term.connectivity[:, 0]] - term.anchor
        exact = u1 / np.sqrt(np.sum(u1**2, axis=1) + term.smoothing**2)[:, None]
        errors.append(np.max(np.abs(dual.q - exact)))
    assert 3.5 < errors[0] / errors[1] < 4.5 and 3.5 < errors[1] / errors[2] < 4.5


def test_dual_stays_in_the_unit_ball_and_its_blocks_stay_positive_definite():
    nodes, term = back_plane(delta=1e-6)
    dual = SlidingDual(term)
    dual.update(slid(nodes, 1e-7, seed=3))            # sticking: slips below δ
    blocks = dual.element_hessians(slid(nodes, 1e-3, seed=4))    # a large step: the update overshoots |q| = 1
    assert np.all(np.linalg.norm(dual.q, axis=1) <= 1.0 + 1e-12)
    assert np.any(np.linalg.norm(dual.q, axis=1) > 0.999)       # some were scaled back to the sphere
    assert np.all(np.linalg.eigvalsh(blocks) > 0.0)
    np.testing.assert_allclose(blocks, np.swapaxes(blocks, 1, 2), rtol=0, atol=1e-12 * np.abs(blocks).max())


def test_dual_update_at_the_same_slips_is_a_no_op():
    nodes, term = back_plane()
    dual = SlidingDual(term)
    dual.update(slid(nodes, 1e-3, seed=5))
    x = slid(nodes, 1e-3, seed=6)
    dual.update(x)
    q = dual.q.copy()
    dual.element_hessians(x)                           # Newton assembles several matrices at one iterate
    np.testing.assert_array_equal(dual.q, q)
