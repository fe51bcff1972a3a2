"""The tension-field skin of the study ``benchmarks/bench_relaxed_skin.py`` (``benchmarks/_relaxed_skin.py``).

Closed forms: the natural width frees the transverse stress; a homogeneous stretch of one
triangle gives the relaxed energy of each state. Derivatives against central differences.
"""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
LAM, MU = 3000.0, 800.0                    # N/m, as the skin's λ_s t_s and μ_s t_s would be


def _module():
    sys.path.insert(0, str(ROOT))
    spec = importlib.util.spec_from_file_location("relaxed_skin", ROOT / "benchmarks" / "_relaxed_skin.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


relaxed = _module()


def spec_energy(a, b):
    """The spec's membrane energy per reference area in squared principal stretches (closed form)."""
    return 0.5 * MU * (a + b - 2 - np.log(a * b)) + 0.5 * LAM * (np.sqrt(a * b) - 1) ** 2


def triangle(a, b):
    """A unit right triangle in the x-y plane, and its copy stretched by √a along x and √b along y."""
    reference = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    return reference, reference * np.array([np.sqrt(a), np.sqrt(b), 1.0])


def relaxed_term(reference):
    from breastcore.fem.skin import SkinMembrane
    return relaxed.RelaxedSkinMembrane.relaxing(SkinMembrane(reference, np.array([[0, 1, 2]]), LAM, MU, 1.0))


def test_natural_width_frees_the_transverse_stress():
    a = np.array([1.0, 1.01, 1.5, 3.0, 10.0])
    n = relaxed.natural_width(a, LAM, MU)
    h = 1e-7
    dW_db = (spec_energy(a, n + h) - spec_energy(a, n - h)) / (2 * h)
    assert np.allclose(dW_db, 0, atol=1e-5 * MU)
    assert n[0] == pytest.approx(1.0) and np.all(np.diff(n) < 0) and np.all(n > 0)
    assert np.allclose(relaxed._principal_derivatives(a, n, LAM, MU)[2], 0, atol=1e-9 * MU)


@pytest.mark.parametrize("a, b, state", [(0.8, 0.7, 0), (0.95, 0.95, 0), (1.5, 0.3, 1), (2.0, 0.5, 1),
                                         (1.5, 1.2, 2), (1.2, 0.99, 2)])
def test_homogeneous_stretch_gives_each_state_its_closed_form(a, b, state):
    reference, x = triangle(a, b)
    term = relaxed_term(reference)
    area = 0.5
    assert term.states(x)[0] == state
    n = relaxed.natural_width(np.array([a]), LAM, MU)[0]
    expected = {0: 0.0, 1: spec_energy(a, n), 2: spec_energy(a, b)}[state]
    assert term.value(x) == pytest.approx(area * expected, rel=1e-12, abs=1e-12)
    assert term.value(x) <= area * spec_energy(a, b) + 1e-12              # relaxation lowers the energy


@pytest.mark.parametrize("a, b", [(1.7, None), (1.0, 0.5)])
def test_energy_and_forces_are_continuous_across_the_state_lines(a, b):
    """Across the wrinkle line ``b = n(a)`` (taut ↔ wrinkled) and across ``a = 1`` (wrinkled ↔ slack) the
    relaxed energy is once differentiable: the nodal forces on either side agree to O(step)."""
    step = 1e-7
    if b is None:                                      # cross the wrinkle line in b
        n = relaxed.natural_width(np.array([a]), LAM, MU)[0]
        sides = [(a, n * (1 - step)), (a, n * (1 + step))]
    else:                                              # cross a = 1 at fixed b
        sides = [(a * (1 - step), b), (a * (1 + step), b)]
    terms = [(relaxed_term(triangle(*ab)[0]), triangle(*ab)[1]) for ab in sides]
    assert [t.states(x)[0] for t, x in terms] == ([1, 2] if b is None else [0, 1])
    energies = [t.value(x) for t, x in terms]
    forces = [t.gradient(x) for t, x in terms]
    scale = MU * 0.5                                   # μ times the triangle's area: the forces' scale
    assert abs(energies[1] - energies[0]) <= 1e-9 * scale
    assert np.abs(forces[1] - forces[0]).max() <= 10 * step * scale


@pytest.mark.parametrize("gap", [1e-9, 1e-6, 0.5])
def test_principal_gap_keeps_its_relative_accuracy_near_equal_stretches(gap):
    """``a − b`` from ``G⁻¹g`` directly: ``√(I₁² − 4q)`` would give ~1e-8 for any gap below it."""
    reference, x = triangle(1 + gap, 1.0)
    term = relaxed_term(reference)
    g = term._edges(x)[1]
    assert relaxed.principal_gap(term.G_inv, g)[0] == pytest.approx(gap, rel=1e-6)


def test_gravity_free_shape_takes_the_spec_hessian():
    """At ``a = b = 1`` round-off picks the state: near it the Hessian is the taut side's (the spec's), while
    the energy and the forces are the relaxed ones, zero there."""
    from breastcore.fem.skin import SkinMembrane
    term, _ = _deformed_patch()
    reference = term.reference_positions
    assert np.all(relaxed.near_triple_point(term._edges(reference)[3], term._kinematics(reference)[4]))
    assert abs(term.value(reference)) <= 1e-12 * MU * term.area.sum()             # zero to round-off
    assert np.abs(term.gradient(reference)).max() <= 1e-12 * MU
    spec = SkinMembrane.element_hessians(term, reference)
    assert np.allclose(term.element_hessians(reference), spec, rtol=1e-12, atol=1e-12 * np.abs(spec).max())


def test_modulus_gradient_is_refused_and_a_switched_off_skin_is_zero():
    """The implicit Jacobian's modulus derivative assumes an energy linear in each modulus: not this one."""
    import copy
    from breastcore.fem.terms import modulus_gradient
    term, x = _deformed_patch()
    with pytest.raises(ValueError, match="not linear"):
        modulus_gradient(term, "mu", x)
    off = copy.copy(term)
    off.lam = off.mu = 0.0
    assert off.value(x) == 0 and not off.gradient(x).any() and not off.element_hessians(x).any()


def _deformed_patch(seed=0, count=60, strain=0.5):
    """``count`` separate triangles, each under its own random homogeneous deformation ``I + strain·N(0, 1)``."""
    rng = np.random.default_rng(seed)
    reference = rng.normal(size=(3 * count, 3))
    triangles = np.arange(3 * count).reshape(count, 3)
    x = reference.copy()
    for t in triangles:
        F = np.eye(3) + strain * rng.normal(size=(3, 3))
        centre = reference[t].mean(0)
        x[t] = centre + (reference[t] - centre) @ F.T
    from breastcore.fem.skin import SkinMembrane
    term = relaxed.RelaxedSkinMembrane.relaxing(SkinMembrane(reference, triangles, LAM, MU, 1.0))
    term.reference_positions = reference
    return term, x


def _central_difference_gradient(term, x, h):
    """``(n, 3)`` central differences of ``term.value`` with step ``h`` (m) in each coordinate."""
    fd = np.zeros_like(x)
    for i in range(len(x)):
        for k in range(3):
            plus, minus = x.copy(), x.copy()
            plus[i, k] += h
            minus[i, k] -= h
            fd[i, k] = (term.value(plus) - term.value(minus)) / (2 * h)
    return fd


def test_gradient_and_hessian_match_central_differences_in_every_state():
    term, x = _deformed_patch()
    states = term.states(x)
    assert set(states) == {0, 1, 2}
    h = 1e-6
    gradient, fd = term.gradient(x), _central_difference_gradient(term, x, h)
    assert np.abs(fd - gradient).max() <= 1e-7 * np.abs(gradient).max()
    hessians, per_element = term.element_hessians(x), term.element_gradients
    for t, nodes in enumerate(term.connectivity):
        columns = []
        for c in range(9):
            plus, minus = x.copy(), x.copy()
            plus[nodes[c // 3], c % 3] += h
            minus[nodes[c // 3], c % 3] -= h
            columns.append(((per_element(plus)[t] - per_element(minus)[t]) / (2 * h)).ravel())
        scale = max(np.abs(hessians[t]).max(), 1.0)
        assert np.abs(np.column_stack(columns) - hessians[t]).max() <= 1e-6 * scale, (t, states[t])


def test_forces_match_central_differences_near_the_triple_point():
    """Strains of 1e-4: some triangles within the triple-point box, where the forces stay exact."""
    term, x = _deformed_patch(seed=2, count=200, strain=1e-4)
    _, _, _, I1, s = term._kinematics(x)
    assert np.any(relaxed.near_triple_point(I1, s)) and not np.all(relaxed.near_triple_point(I1, s))
    gradient, fd = term.gradient(x), _central_difference_gradient(term, x, h=1e-7)
    # the differences are good to ~1e-5 here: W's round-off at strains of 1e-4 (ε/strain² per h) and the
    # kinks at the state lines (O(h/strain)); a force of the wrong state would be off by O(1)
    assert np.abs(fd - gradient).max() <= 1e-3 * np.abs(gradient).max()


@pytest.mark.parametrize("strain, tolerance", [(0.5, 1e-9), (1e-2, 1e-9), (1e-3, 3e-8), (1e-4, 3e-7)])
def test_wrinkled_and_slack_blocks_are_positive_semidefinite(strain, tolerance):
    """The relaxation's point: no compressed triangle contributes a negative eigenvalue (to round-off, which
    grows as ε/s² towards the triple point: module Notes). Slack blocks are zero. Near the triple point the
    blocks are the spec's (not checked here)."""
    term, x = _deformed_patch(seed=1, count=300, strain=strain)
    _, _, _, I1, s = term._kinematics(x)
    states, eigenvalues = term.states(x), np.linalg.eigvalsh(term.element_hessians(x))
    states = np.where(relaxed.near_triple_point(I1, s), -1, states)
    assert np.any(states == 0) and np.any(states == 1)
    assert np.all(eigenvalues[states == 0] == 0)
    wrinkled = eigenvalues[states == 1]
    assert np.all(wrinkled.min(axis=1) >= -tolerance * np.abs(wrinkled).max(axis=1))


def test_relaxed_model_solves_coarse_standing_to_equilibrium():
    """The swapped term reaches the solver; its equilibrium's residual meets the solver's tolerance."""
    from breastcore.model.mesh import mesh_level
    from breastcore.model.parameters import Parameters
    from breastcore.model.postures import paper_postures
    model = relaxed.RelaxedSkinModel(mesh_level("coarse"))
    params, standing = Parameters(), paper_postures()[0]
    solution = model.solve(params, standing)
    problem = model.problem(params, standing)
    assert isinstance(problem.energy.terms[1], relaxed.RelaxedSkinMembrane)
    residual = np.linalg.norm(problem.gradient(problem.free(solution.position)))
    assert residual <= model.tolerance(params, standing)
    assert solution.negative_eigenvalues == 0
