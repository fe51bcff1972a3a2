"""Newton's chord steps (``reuse``): same minimiser, fewer factorisations; and the option's checks."""

import numpy as np
import pytest
import scipy.sparse as sp

from breastcore.forward.model import ForwardModel
from breastcore.forward.options import SolverOptions
from breastcore.inverse.measurements import measure
from breastcore.linalg import pardiso
from breastcore.model.mesh import mesh_level
from breastcore.model.parameters import Parameters
from breastcore.model.postures import paper_postures
from breastcore.nonlinear.newton import newton


class QuarticProblem:
    """``E(z) = ½ zᵀAz + ¼ Σ z⁴ − bᵀz`` with ``A`` the 1-D Laplacian plus identity: strictly convex,
    its Hessian ``A + 3 diag(z²)`` changes with ``z`` (a chord step is not a Newton step)."""

    energy_scale = 1.0
    pattern = None

    def __init__(self, n=200):
        self.A = sp.diags([-np.ones(n - 1), 3.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
        self.b = np.linspace(1.0, 4.0, n)

    def value(self, z):
        return float(0.5 * z @ (self.A @ z) + 0.25 * np.sum(z**4) - self.b @ z)

    def gradient(self, z):
        return self.A @ z + z**3 - self.b

    def hessian(self, z, project=False):
        return (self.A + sp.diags(3.0 * z**2)).tocsr()


def test_chord_steps_reach_the_same_minimiser_with_fewer_factorisations():
    problem = QuarticProblem()
    z0 = np.zeros(200)
    fresh = newton(problem, z0, 1e-10, 100)
    chord = newton(problem, z0, 1e-10, 100, reuse=0.5)
    assert fresh.success and chord.success
    assert fresh.factorizations == fresh.iterations                     # one per iteration, as before
    assert chord.factorizations < chord.iterations                      # some steps reused a factor
    assert np.linalg.norm(problem.gradient(chord.x)) <= 1e-10           # the equilibrium residual itself
    # both are the unique minimiser of a strictly convex energy, to the gradient tolerance / min eigenvalue
    assert np.max(np.abs(chord.x - fresh.x)) < 1e-9


def test_chord_steps_give_the_same_cap_equilibrium_on_coarse(monkeypatch):
    import breastcore.nonlinear.newton as newton_module
    mesh = mesh_level("coarse")
    params = Parameters()
    standing = paper_postures()[0]
    fresh = ForwardModel(mesh, SolverOptions()).solve(params, standing)
    taken = []
    chord_step = newton_module._chord_step
    monkeypatch.setattr(newton_module, "_chord_step", lambda *a: taken.append(chord_step(*a)) or taken[-1])
    chord = ForwardModel(mesh, SolverOptions(reuse_factor=0.5)).solve(params, standing)
    assert sum(step is not None for step in taken) > 0             # the solve did take chord steps
    assert chord.gradient_norm <= chord.tolerance
    m_fresh = np.array(list(measure(mesh, fresh.position, "paper15").values()))
    m_chord = np.array(list(measure(mesh, chord.position, "paper15").values()))
    assert np.max(np.abs(m_chord / m_fresh - 1.0)) < 1e-7


@pytest.mark.parametrize("bad", [-0.1, 1.0])
def test_reuse_factor_outside_zero_one_is_refused(bad):
    with pytest.raises(ValueError, match="reuse_factor"):
        SolverOptions(reuse_factor=bad)


class SoftModeProblem:
    """``E(z) = ½ zᵀAz + n (¼ m⁴ − ½ κ m²) − bᵀz`` with ``m`` the mean of ``z``, ``A = I`` plus a weak
    1-D Laplacian and κ = 1.05: the Hessian ``A + (3m² − κ)/n 11ᵀ`` has a positive diagonal but, near
    ``m = 0``, one negative eigenvalue (the mean mode, 1 − κ), as a soft mode of the cap does. The
    projected Hessian clips the mode's curvature ``3m² − κ`` at 0."""

    energy_scale = 1.0
    pattern = None
    kappa = 1.05

    def __init__(self, n=50):
        self.n = n
        self.A = (sp.identity(n) + 0.1 * sp.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]))
        self.b = 1e-3 * np.cos(np.arange(n))

    def value(self, z):
        m = z.mean()
        return float(0.5 * z @ (self.A @ z) + self.n * (0.25 * m**4 - 0.5 * self.kappa * m**2) - self.b @ z)

    def gradient(self, z):
        m = z.mean()
        return self.A @ z + (m**3 - self.kappa * m) - self.b

    def hessian(self, z, project=False):
        curvature = 3.0 * z.mean() ** 2 - self.kappa
        mode = np.full((self.n, self.n), (max(curvature, 0.0) if project else curvature) / self.n)
        return sp.csr_matrix(self.A.toarray() + mode)


def test_inertia_shift_reaches_a_minimum_through_the_indefinite_region(caplog):
    from breastcore.linalg import pardiso
    if not pardiso.available():
        pytest.skip("the inertia shift needs PARDISO's inertia")
    problem = SoftModeProblem()
    z0 = np.full(50, 1e-3)
    assert np.linalg.eigvalsh(problem.hessian(z0).toarray()).min() < 0
    with caplog.at_level("DEBUG", logger="breastcore.nonlinear.newton"):
        result = newton(problem, z0, 1e-10, 100, inertia_shift=True)
    modes = [r.message.split("mode=")[1].split()[0] for r in caplog.records if "mode=" in r.message]
    # σ = 0.01 leaves the mean mode's eigenvalue (1 − κ + 0.01 diag) negative: refused; 0.1 makes it positive
    assert "shift0.1" in modes and "shift0.01" not in modes
    assert result.success and np.linalg.norm(problem.gradient(result.x)) <= 1e-10
    assert np.linalg.eigvalsh(problem.hessian(result.x).toarray()).min() > 0      # a minimum, not a saddle
    plain = newton(problem, z0, 1e-10, 100)
    # the plain exact step heads for the saddle at m = 0 (|g| ~ 1e-8 after one step); the shifted one leaves it
    assert plain.history[1] < 1e-6 < result.history[1]


def test_sliding_dual_and_inertia_shift_give_the_same_cap_equilibrium_on_coarse(monkeypatch):
    from breastcore.fem.sliding_dual import SlidingDual
    mesh = mesh_level("coarse")
    params = Parameters()
    exact = ForwardModel(mesh, SolverOptions(sliding_dual=False, inertia_shift=False)).solve(params, paper_postures()[1])
    used = []
    blocks = SlidingDual.element_hessians
    monkeypatch.setattr(SlidingDual, "element_hessians", lambda self, x: used.append(1) or blocks(self, x))
    dual = ForwardModel(mesh, SolverOptions(sliding_dual=True, inertia_shift=True)).solve(params, paper_postures()[1])
    assert used                                                    # the steps did use the dual blocks
    assert dual.gradient_norm <= dual.tolerance
    m_exact = np.array(list(measure(mesh, exact.position, "paper15").values()))
    m_dual = np.array(list(measure(mesh, dual.position, "paper15").values()))
    assert np.max(np.abs(m_dual / m_exact - 1.0)) < 1e-7


class _MisleadingRelease(QuarticProblem):
    """A problem whose released right-hand side points uphill (``−g``): only the fallback steps,
    which must solve for ``g`` with the release cleared, can descend."""

    def __init__(self):
        super().__init__(40)
        self.calls = []

    def step_gradient(self, z, g, release=True):
        self.calls.append(release)
        return -g if release else g


def test_a_failed_released_step_falls_back_to_steps_for_the_gradient():
    problem = _MisleadingRelease()
    result = newton(problem, np.zeros(40), 1e-10, 60)
    assert result.success and result.projected_steps == result.iterations   # every step a fallback one
    assert False in problem.calls and True in problem.calls


@pytest.mark.parametrize("posture", [0, 2], ids=["standing", "fours"])
def test_released_sliding_steps_give_the_same_equilibrium_on_medium(monkeypatch, posture):
    """``sliding_release`` changes the steps only: it does release nodes on the way, none at the
    equilibrium, and the measurements agree with the primal-dual steps' to the solve's accuracy."""
    from breastcore.fem.sliding_dual import SlidingDual
    mesh, params = mesh_level("medium"), Parameters()
    plain = ForwardModel(mesh, SolverOptions(sliding_release=False)).solve(params, paper_postures()[posture])
    released = []
    release = SlidingDual.release

    def counted_release(self, x, g):
        correction = release(self, x, g)
        released.append(int(np.count_nonzero(correction.any(axis=1))))
        return correction
    monkeypatch.setattr(SlidingDual, "release", counted_release)
    model = ForwardModel(mesh, SolverOptions(sliding_release=True))
    solution = model.solve(params, paper_postures()[posture])
    assert max(released) > 0                                         # nodes were released on the way
    assert solution.gradient_norm <= solution.tolerance and solution.negative_eigenvalues == 0
    problem = model.problem(params, paper_postures()[posture])
    z = problem.free(solution.position)
    g = problem.gradient(z)
    np.testing.assert_array_equal(problem.step_gradient(z, g), g)   # none at the equilibrium
    m_plain = np.array(list(measure(mesh, plain.position, "paper15").values()))
    m_released = np.array(list(measure(mesh, solution.position, "paper15").values()))
    assert np.max(np.abs(m_released / m_plain - 1.0)) < 1e-7


@pytest.mark.parametrize("name", ["sliding_dual", "sliding_release", "inertia_shift"])
def test_step_options_must_be_booleans(name):
    with pytest.raises(ValueError, match=name):
        SolverOptions(**{name: "yes"})


def test_numpy_scalars_in_the_step_options_become_python_ones():
    """Options built from arrays (e.g. a grid) must stay JSON-able in a dataset's spec."""
    import json
    options = SolverOptions(sliding_dual=np.bool_(False), inertia_shift=np.bool_(True),
                            mixed_precision_min_dofs=np.int64(5000))
    assert type(options.sliding_dual) is bool and type(options.mixed_precision_min_dofs) is int
    json.dumps(options.__dict__)


def _cold_standing(options, mesh_name="coarse", factors=(1.0,) * 6):
    model = ForwardModel(mesh_level(mesh_name), options)
    params = Parameters()
    params = params.with_identified(np.array(params.identified()) * np.array(factors))
    return model, model.solve(params, paper_postures()[0])


@pytest.mark.skipif(not pardiso.available(), reason="inexact steps need PARDISO's single-precision factors")
def test_inexact_newton_steps_reach_the_same_equilibrium_on_coarse():
    """``step_rtol`` 1e-3 against directions refined to 1e-10: both stop at |g| ≤ tolerance, and the
    equilibria agree to what that tolerance allows."""
    model, refined = _cold_standing(SolverOptions(step_rtol=1e-10))
    _, inexact = _cold_standing(SolverOptions(step_rtol=1e-3))
    problem = model.problem(Parameters(), paper_postures()[0])
    g = problem.gradient(problem.free(inexact.position))
    assert np.linalg.norm(g) <= inexact.tolerance                     # an equilibrium, recomputed here
    assert inexact.negative_eigenvalues == 0
    m_refined = np.array(list(measure(model.mesh, refined.position, "paper15").values()))
    m_inexact = np.array(list(measure(model.mesh, inexact.position, "paper15").values()))
    assert 0 < np.max(np.abs(m_inexact / m_refined - 1.0)) < 1e-7     # another path, the same equilibrium


def test_step_rtol_must_be_at_least_the_refinement_tolerance_and_below_1():
    for bad in (0.0, 1e-11, 1.0, -1e-3, True):
        with pytest.raises(ValueError, match="step_rtol"):
            SolverOptions(step_rtol=bad)


def test_shifts_are_futile_above_the_pivot_cap_or_where_they_failed_with_as_many_pivots():
    from breastcore.nonlinear.indefinite import MAX_SHIFT_PIVOTS, shifts_futile
    assert not shifts_futile(MAX_SHIFT_PIVOTS, None)
    assert shifts_futile(MAX_SHIFT_PIVOTS + 1, None)
    assert shifts_futile(3, failed_at=3) and shifts_futile(4, failed_at=3)
    assert not shifts_futile(2, failed_at=3)                       # fewer negative pivots: worth a try again


@pytest.mark.skipif(not pardiso.available(), reason="the shifts need PARDISO's inertia")
def test_skipping_futile_shifts_saves_factorisations_and_keeps_the_equilibrium(monkeypatch):
    """A cold standing solve on medium 30 % off Λ̄ meets indefinite step matrices whose shifts fail;
    skipping the shifts that the rule calls futile must not change a step that a shift would have
    given, here: the same equilibrium bit for bit, fewer factorisations."""
    import breastcore.nonlinear.newton as newton_module
    counts = {}

    def counting(skip):
        real = newton_module.newton

        def run(*args, **kwargs):
            result = real(*args, **kwargs)
            counts[skip] = counts.get(skip, 0) + result.factorizations
            return result
        return run

    base = dict(step_rtol=1e-10)
    for skip in (False, True):
        monkeypatch.setattr("breastcore.forward.continuation.newton", counting(skip))
        _, solution = _cold_standing(SolverOptions(skip_futile_shifts=skip, **base), "medium",
                                     (1.3, 0.7, 0.7, 1.3, 1.3, 0.7))
        if skip:
            np.testing.assert_array_equal(solution.position, tried.position)
        tried = solution
    assert counts[True] < counts[False]


@pytest.mark.skipif(not pardiso.available(), reason="the deep phase is told by PARDISO's inertia")
def test_deep_indefinite_skips_take_the_same_steps_with_fewer_factorisations(monkeypatch, caplog):
    """A cold standing solve on thin 30 % off Λ̄ starts with 22, 33, 27 and 20 negative pivots: its
    next steps are projected whatever their exact factor says, so skipping those factorisations must
    give the same iterates bit for bit, with fewer factorisations, and the log must show the skips."""
    import breastcore.nonlinear.newton as newton_module
    counts, solutions, skipped = {}, {}, {}
    real = newton_module.newton

    def counting(skips):
        def run(*args, **kwargs):
            result = real(*args, **kwargs)
            counts[skips] = counts.get(skips, 0) + result.factorizations
            return result
        return run

    for skips in (0, 3):
        monkeypatch.setattr("breastcore.forward.continuation.newton", counting(skips))
        with caplog.at_level("DEBUG", logger="breastcore.nonlinear.newton"):
            caplog.clear()
            _, solutions[skips] = _cold_standing(SolverOptions(deep_indefinite_skips=skips), "thin",
                                                 (1.3, 0.7, 0.7, 1.3, 1.3, 0.7))
        skipped[skips] = sum("inertia skipped" in r.message for r in caplog.records)
    assert skipped == {0: 0, 3: 3}                                  # one deep phase: 22 pivots, then 3 skips
    np.testing.assert_array_equal(solutions[3].position, solutions[0].position)
    assert solutions[3].iterations == solutions[0].iterations
    assert counts[3] == counts[0] - skipped[3]                      # one exact factorisation per skip
    assert solutions[3].negative_eigenvalues == 0                   # a minimum, checked at the solution


class ManySoftModesProblem(SoftModeProblem):
    """:class:`SoftModeProblem` with one soft mode per block of 3 dofs: 20 blocks, each mean ``m_j`` in
    the double well ``3 (¼ m⁴ − ½ κ m²)`` with κ = 1.5; near ``z = 0`` the Hessian has 20 negative
    eigenvalues, more than :data:`~breastcore.nonlinear.indefinite.DEEP_INDEFINITE_PIVOTS`."""

    kappa = 1.5

    def __init__(self, n=60):
        super().__init__(n)
        self.blocks = np.arange(n) // 3

    def _means(self, z):
        return np.bincount(self.blocks, z) / 3.0

    def value(self, z):
        m = self._means(z)
        return float(0.5 * z @ (self.A @ z) + 3.0 * np.sum(0.25 * m**4 - 0.5 * self.kappa * m**2) - self.b @ z)

    def gradient(self, z):
        m = self._means(z)
        return self.A @ z + (m**3 - self.kappa * m)[self.blocks] - self.b

    def hessian(self, z, project=False):
        curvature = 3.0 * self._means(z) ** 2 - self.kappa
        curvature = np.maximum(curvature, 0.0) if project else curvature
        same = self.blocks[:, None] == self.blocks[None, :]
        return sp.csr_matrix(self.A.toarray() + same * curvature[self.blocks][:, None] / 3.0)


@pytest.mark.skipif(not pardiso.available(), reason="the deep phase is told by PARDISO's inertia")
def test_a_failed_skipped_step_falls_back_to_a_fresh_one(monkeypatch, caplog):
    """Where the projected step of a skipped iteration finds no descent step, the iteration takes the
    full fresh step (exact factorisation, shifts, projection) instead of failing."""
    import breastcore.nonlinear.newton as newton_module
    problem = ManySoftModesProblem()
    z0 = np.full(60, 1e-3)
    assert np.sum(np.linalg.eigvalsh(problem.hessian(z0).toarray()) < 0) == 20
    real, calls, failed_tries = newton_module.projected_step, [], 2

    def failing_once(*args):
        calls.append(args)
        return (None, "shift", failed_tries) if len(calls) == 2 else real(*args)   # 1: the first fresh step's
    monkeypatch.setattr(newton_module, "projected_step", failing_once)
    with caplog.at_level("DEBUG", logger="breastcore.nonlinear.newton"):
        result = newton(problem, z0, 1e-10, 100, inertia_shift=True, skip_futile_shifts=True, deep_skips=3)
    modes = [r.message.split("mode=")[1].split(" neg=")[0] for r in caplog.records if "mode=" in r.message]
    assert modes[0] == "project" and not modes[1].endswith("(inertia skipped)")   # the first skip failed
    assert any(mode.endswith("(inertia skipped)") for mode in modes[2:])          # the next ones were taken
    assert result.success and np.linalg.norm(problem.gradient(result.x)) <= 1e-10
    assert np.linalg.eigvalsh(problem.hessian(result.x).toarray()).min() > 0      # a minimum
    plain = newton(problem, z0, 1e-10, 100, inertia_shift=True, skip_futile_shifts=True)
    # the same steps: one exact factorisation saved per skipped step, the failed try's counted
    np.testing.assert_array_equal(result.x, plain.x)
    skipped = sum(mode.endswith("(inertia skipped)") for mode in modes)
    assert result.factorizations == plain.factorizations - skipped + failed_tries


@pytest.mark.skipif(not pardiso.available(), reason="the deep phase is told by PARDISO's inertia")
@pytest.mark.parametrize("options", [dict(), dict(inertia_shift=True)], ids=["plain", "every-shift"])
def test_deep_skips_do_nothing_where_the_exact_factorisation_could_change_the_step(options, caplog):
    """Without ``inertia_shift`` an indefinite exact step that descends is taken; without
    ``skip_futile_shifts`` the shifts are tried at any depth: skipping there would change the steps,
    so ``deep_skips`` must not skip, and the solve must equal the one without it."""
    problem = ManySoftModesProblem()
    z0 = np.full(60, 1e-3)
    with caplog.at_level("DEBUG", logger="breastcore.nonlinear.newton"):
        skipping = newton(problem, z0, 1e-10, 100, deep_skips=3, **options)
    assert not [r for r in caplog.records if "inertia skipped" in r.message]
    plain = newton(problem, z0, 1e-10, 100, **options)
    np.testing.assert_array_equal(skipping.x, plain.x)
    assert skipping.factorizations == plain.factorizations


@pytest.mark.parametrize("bad", [-1, 1.5, True, "3"])
def test_deep_indefinite_skips_must_be_a_count(bad):
    with pytest.raises(ValueError, match="deep_indefinite_skips"):
        SolverOptions(deep_indefinite_skips=bad)


class _FixedFactor:
    """A stand-in mixed-precision factor whose (refined) solve returns a given direction."""

    mixed = True

    def __init__(self, direction):
        self.direction = direction

    def solve(self, g):
        return -self.direction


def test_the_retaken_last_step_is_kept_only_where_it_is_an_equilibrium_too():
    from breastcore.nonlinear.newton import _refined_if_last
    problem = QuarticProblem(50)
    exact = newton(problem, np.zeros(50), 1e-13, 100).x               # the minimiser, to round-off
    z0 = exact + 1e-4                                                  # one Newton step from the minimiser
    g = problem.gradient(z0)
    tolerance = 1e-6
    direction = np.linalg.solve(problem.hessian(z0).toarray(), -g)
    inexact = z0 + direction * (1 + 1e-4)                              # a slightly inexact step, converged
    assert np.linalg.norm(problem.gradient(inexact)) <= tolerance
    z, _, g_z = _refined_if_last(problem, _FixedFactor(direction), z0, g, 1.0, inexact,
                                 problem.value(inexact), tolerance)
    np.testing.assert_array_equal(z, z0 + direction)                   # retaken along the refined direction
    np.testing.assert_array_equal(g_z, problem.gradient(z))
    worse = direction + 1e-2                                           # a "refined" direction that is worse
    z, energy, _ = _refined_if_last(problem, _FixedFactor(worse), z0, g, 1.0, inexact, problem.value(inexact),
                                    tolerance)
    np.testing.assert_array_equal(z, inexact)                          # the converged inexact point is kept
    assert energy == problem.value(inexact)
    far = z0 + 0.5 * direction                                         # a step that does not end the solve
    z, _, g_z = _refined_if_last(problem, _FixedFactor(direction), z0, g, 0.5, far, problem.value(far), tolerance)
    np.testing.assert_array_equal(z, far)
    assert np.linalg.norm(g_z) > tolerance
