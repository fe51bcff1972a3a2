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


def test_energy_is_continuous_across_the_wrinkle_line():
    a = 1.7
    n = relaxed.natural_width(np.array([a]), LAM, MU)[0]
    below, above = (relaxed_term(triangle(a, b)[0]).value(triangle(a, b)[1]) for b in (n * (1 - 1e-9), n * (1 + 1e-9)))
    assert below == pytest.approx(above, rel=1e-8)


def _deformed_patch(seed=0, count=60):
    rng = np.random.default_rng(seed)
    reference = rng.normal(size=(3 * count, 3))
    triangles = np.arange(3 * count).reshape(count, 3)
    x = reference.copy()
    for t in triangles:
        F = np.eye(3) + 0.5 * rng.normal(size=(3, 3))
        centre = reference[t].mean(0)
        x[t] = centre + (reference[t] - centre) @ F.T
    from breastcore.fem.skin import SkinMembrane
    return relaxed.RelaxedSkinMembrane.relaxing(SkinMembrane(reference, triangles, LAM, MU, 1.0)), x


def test_gradient_and_hessian_match_central_differences_in_every_state():
    term, x = _deformed_patch()
    states = term.states(x)
    assert set(states) == {0, 1, 2}
    h = 1e-6
    gradient, fd = term.gradient(x), np.zeros_like(x)
    for i in range(len(x)):
        for k in range(3):
            plus, minus = x.copy(), x.copy()
            plus[i, k] += h
            minus[i, k] -= h
            fd[i, k] = (term.value(plus) - term.value(minus)) / (2 * h)
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


def test_wrinkled_and_slack_blocks_are_positive_semidefinite():
    """The relaxation's point: no compressed triangle contributes a negative eigenvalue."""
    term, x = _deformed_patch(seed=1)
    states, eigenvalues = term.states(x), np.linalg.eigvalsh(term.element_hessians(x))
    for state in (0, 1):
        assert np.any(states == state)
        blocks = eigenvalues[states == state]
        assert blocks.min() >= -1e-9 * max(np.abs(blocks).max(), 1.0)


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
