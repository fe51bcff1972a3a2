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


# --- released nodes (SlidingDual.release) ---------------------------------------------------------

def _demand(term, x, gradient):
    u, _, root = term._slip(x)
    return u / root[:, None] - gradient[term.connectivity[:, 0]] / term.weight[:, None]


def test_release_saturates_the_force_of_sticking_nodes_pulled_past_the_threshold():
    """Released: the step's sliding force becomes ``w d/|d|``; the rest of the gradient is kept."""
    from breastcore.fem.sliding_dual import RELEASE_DEMAND
    nodes, term = back_plane(delta=1e-6)
    x = slid(nodes, 2e-7, seed=7)                                   # every node sticks: |u| ≲ δ
    rng = np.random.default_rng(8)
    pull = rng.uniform(0.2, 3.0, len(nodes))[:, None] * np.array([1.0, 0.0, 0.4]) / np.hypot(1.0, 0.4)
    back = term.connectivity[:, 0]
    u, _, root = term._slip(x)
    gradient = np.zeros_like(x)
    gradient[back] = term.weight[:, None] * (u / root[:, None] - pull[back])     # demand = pull
    dual = SlidingDual(term)
    correction = dual.release(x, gradient)
    demand = _demand(term, x, gradient)
    np.testing.assert_allclose(demand, pull[back], rtol=1e-12, atol=1e-12)
    released = np.linalg.norm(demand, axis=1) > RELEASE_DEMAND
    assert 0 < released.sum() < len(back)
    force = (gradient + correction)[back] - (gradient[back] - term.weight[:, None] * u / root[:, None])
    unit = demand / np.linalg.norm(demand, axis=1)[:, None]
    np.testing.assert_allclose(force[released], term.weight[released, None] * unit[released], rtol=1e-12)
    np.testing.assert_array_equal(correction[back[~released]], 0.0)


def test_released_blocks_are_free_along_the_demand_and_the_others_unchanged():
    nodes, term = back_plane(delta=1e-6)
    x = slid(nodes, 2e-7, seed=9)
    back = term.connectivity[:, 0]
    u, _, root = term._slip(x)
    gradient = np.zeros_like(x)
    gradient[back] = term.weight[:, None] * (u / root[:, None] - np.array([2.0, 0.0, 0.0]) *
                                            np.linspace(0.1, 1.5, len(back))[:, None])
    dual, plain = SlidingDual(term), SlidingDual(term)
    dual.release(x, gradient)
    released = np.linalg.norm(_demand(term, x, gradient), axis=1) > 1.05
    blocks, before = dual.element_hessians(x), plain.element_hessians(x)
    assert 0 < released.sum() < len(back)
    e = np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(blocks[released] @ e, 0.0, atol=1e-12 * np.abs(blocks).max())
    for v in (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])):     # across the demand: w/r
        np.testing.assert_allclose(blocks[released] @ v, (term.weight / root)[released, None] * v, rtol=0,
                                   atol=1e-12 * np.abs(blocks).max())
    np.testing.assert_array_equal(blocks[~released], before[~released])
    np.testing.assert_array_equal(dual.element_hessians(slid(nodes, 2e-7, seed=10)),   # elsewhere: not released
                                  plain.element_hessians(slid(nodes, 2e-7, seed=10)))
    dual.release(x, gradient)
    dual.clear_release()
    np.testing.assert_array_equal(dual.element_hessians(x), plain.element_hessians(x))   # cleared: none released


def test_no_release_beyond_the_slip_limit_at_an_equilibrium_or_without_sliding_resistance():
    import warnings
    from breastcore.fem.loads import Chassaignac as Term
    from breastcore.fem.sliding_dual import RELEASE_MAX_SLIP
    nodes, term = back_plane(delta=1e-6)
    back = term.connectivity[:, 0]
    x = nodes.copy()
    x[:, 0] += 2 * RELEASE_MAX_SLIP * 1e-6                          # every node slips 20 δ
    pulled = np.zeros_like(x)
    pulled[back] = -3.0 * term.weight[:, None] * np.array([1.0, 0.0, 0.0])
    assert not SlidingDual(term).release(x, pulled).any()
    x = slid(nodes, 2e-7, seed=11)
    assert not SlidingDual(term).release(x, np.zeros_like(x)).any()           # equilibrium: |d| = |u|/r < 1
    free = Term(nodes, np.array([[0, 4, 5], [0, 5, 1]]), coefficient=0.0, smoothing=1e-6)    # c = 0: w = 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not SlidingDual(free).release(nodes, np.ones_like(nodes)).any()


class SpringsOnTheBack:
    """Back nodes held by springs ``½ k |u − a_n|²`` and the smoothed sliding term: the
    unsmoothed law's equilibrium is ``u_n = a_n (1 − w_n / (k |a_n|))`` where ``k |a_n| > w_n``,
    else ``u_n = 0``."""

    def __init__(self, release, k=1.0):
        self.nodes, self.term = back_plane(n=3, delta=1e-6)
        self.k = k
        rng = np.random.default_rng(12)
        self.a = np.zeros_like(self.nodes)
        self.a[:, [0, 2]] = rng.uniform(-1.0, 1.0, (len(self.nodes), 2))
        self.a *= (self.term.weight / k * np.linspace(0.3, 3.0, len(self.nodes)))[:, None] / np.linalg.norm(
            self.a, axis=1)[:, None]
        self.dual = SlidingDual(self.term)
        self.release = release
        self.energy_scale = float(np.sum(self.term.weight) * 1e-3)
        self.pattern = None

    def full(self, z):
        return self.nodes + z.reshape(-1, 3)

    def value(self, z):
        u = z.reshape(-1, 3)
        return 0.5 * self.k * float(np.sum((u - self.a) ** 2)) + self.term.value(self.full(z))

    def gradient(self, z):
        return (self.k * (z.reshape(-1, 3) - self.a) + self.term.gradient(self.full(z))).ravel()

    def _matrix(self, blocks):
        import scipy.sparse as sp
        return sp.csr_matrix(sp.block_diag(list(blocks)) + self.k * sp.identity(blocks.shape[0] * 3))

    def hessian(self, z, project=False):
        return self._matrix(self.term.element_hessians(self.full(z)))

    def step_hessian(self, z, project=False):
        return self._matrix(self.dual.element_hessians(self.full(z)))

    def step_gradient(self, z, g):
        if not self.release:
            return g
        return g + self.dual.release(self.full(z), g.reshape(-1, 3)).ravel()

    def unsmoothed_solution(self):
        size = np.linalg.norm(self.a, axis=1)
        return self.a * np.clip(1.0 - self.term.weight / (self.k * size), 0.0, None)[:, None]


def test_a_released_step_lands_on_the_unsmoothed_law_and_the_solve_on_the_same_equilibrium():
    """Springs pulling back nodes from rest: the first released step is the exact semismooth Newton
    step of the unsmoothed law, so it lands on that law's equilibrium, where the primal-dual step
    alone moves the sticking nodes by a few δ; both solves end on the same equilibrium."""
    from breastcore.nonlinear.newton import newton
    released, plain = SpringsOnTheBack(release=True), SpringsOnTheBack(release=False)
    z0 = np.zeros(released.nodes.size)
    expected = released.unsmoothed_solution()
    slipping = np.linalg.norm(expected, axis=1) > 0
    assert 3 <= slipping.sum() < len(slipping)                                 # some nodes slip, some stick
    first = newton(released, z0, 1e-30, max_iterations=1).x.reshape(-1, 3)
    np.testing.assert_allclose(first, expected, rtol=0, atol=2e-6)         # the unsmoothed law: O(δ) off
    plain_first = newton(plain, z0, 1e-30, max_iterations=1).x.reshape(-1, 3)
    assert np.all(np.linalg.norm(plain_first, axis=1) < 5e-6)              # δ-sized moves only
    tolerance = 1e-10 * np.linalg.norm(released.k * released.a)
    with_release, without = newton(released, z0, tolerance), newton(plain, z0, tolerance)
    assert with_release.success and without.success
    np.testing.assert_allclose(with_release.x, without.x, rtol=0, atol=1e-9)
