r"""Exact inversion-free step filtering (seed 004) and its use in the Newton pre-check.

The per-cell step is checked against a brute-force search on the determinants
themselves (dense sampling of :math:`\alpha`, then bisection), against closed
forms (a uniform shrink :math:`x \mapsto (1 - s\alpha) x` has volume ratio
:math:`(1 - s\alpha)^d`, so the critical step is :math:`(1 - \eta^{1/d})/s`),
and on meshes against :math:`J = \det(I + \nabla u)` evaluated by DOLFINx at the
filtered state. The Newton tests solve the cantilever bend at 20 times its
load in one step, where the first Newton directions would invert cells.
"""

from pathlib import Path

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

import hyperfem as hf
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load
from hyperfem.errors import ParameterError
from hyperfem.io import PointProbe
from hyperfem.solver.newton import STEP_SAFETY
from hyperfem.solver.step_filter import (
    StepFilter,
    exact_filter_applies,
    first_volume_crossing,
    max_step_fractions,
    volume_ratio_coefficients,
)

MESH = Path(__file__).resolve().parent.parent / "meshes" / "beam_h2.msh"
ETA = 0.1


def _brute_force(D, P, eta=ETA, samples=4001):
    """Smallest alpha in (0, 1] with det(D + alpha P) / det D <= eta: dense sampling, then bisection per cell."""
    det0 = np.linalg.det(D)
    alphas = np.linspace(0.0, 1.0, samples)
    ratios = np.stack([np.linalg.det(D + a * P) / det0 for a in alphas], axis=1)
    below = ratios <= eta
    hit = below.any(axis=1)
    out = np.ones(len(D))
    first = np.argmax(below, axis=1)
    lo, hi = alphas[first[hit] - 1], alphas[first[hit]]
    Dh, Ph, dh = D[hit], P[hit], det0[hit]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        above = np.linalg.det(Dh + mid[:, None, None] * Ph) / dh > eta
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    out[hit] = lo
    return out, ratios, alphas


@pytest.mark.parametrize("d", [2, 3])
def test_cell_steps_match_brute_force(d):
    rng = np.random.default_rng(10 + d)
    n = 400
    D = np.eye(d) + 0.3 * rng.standard_normal((n, d, d))
    D[np.linalg.det(D) < 0, 0] *= -1.0  # either orientation works; keep a mix below
    D[::3, [0, 1]] = D[::3, [1, 0]]
    P = rng.standard_normal((n, d, d)) * rng.uniform(0.0, 4.0, (n, 1, 1))
    alpha = max_step_fractions(D, P, ETA)
    ref, ratios, alphas = _brute_force(D, P)
    limited = ref < 1.0
    assert 0.2 * n < limited.sum() < 0.9 * n  # the sample has both kinds of cells
    np.testing.assert_allclose(alpha, ref, rtol=0, atol=1e-8)
    # never past the root: the volume ratio at the step is >= eta (to round-off) ...
    at = np.linalg.det(D + alpha[:, None, None] * P) / np.linalg.det(D)
    assert np.all(at >= ETA - 1e-10)
    # ... and above eta on the whole sampled [0, alpha)
    before = alphas[None, :] < alpha[:, None]
    assert np.all(ratios[before] > ETA)
    # and the limited cells are at eta there (the step is the largest)
    np.testing.assert_allclose(at[limited], ETA, atol=1e-9)


def test_coefficients_are_the_determinant_polynomial():
    rng = np.random.default_rng(1)
    for d in (2, 3):
        D, P = rng.standard_normal((20, d, d)), rng.standard_normal((20, d, d))
        a = volume_ratio_coefficients(D, P)
        for t in (-1.3, 0.4, 2.0):
            poly = a[0] + t * a[1] + t**2 * a[2] + t**3 * a[3]
            np.testing.assert_allclose(poly, np.linalg.det(D + t * P), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("d", [2, 3])
def test_uniform_shrink_closed_form(d):
    D = np.eye(d)[None] * np.array([1.0, 2.0, 0.5])[:, None, None]
    for s in (0.3, 1.0, 2.0, 10.0):
        alpha = max_step_fractions(D, -s * D, ETA)
        expected = min(1.0, (1.0 - ETA ** (1.0 / d)) / s)
        np.testing.assert_allclose(alpha, expected, rtol=1e-13, atol=1e-15)


def test_degenerate_and_special_polynomials():
    g0 = 1.0 - ETA
    # no direction, pure growth, linear shrink, quadratic, a tiny leading coefficient
    b = np.array([0.0, 5.0, -2.0 * g0, 0.0, -1.0, -1.0])
    c = np.array([0.0, 3.0, 0.0, -4.0 * g0, 0.0, 0.0])
    d = np.array([0.0, 1.0, 0.0, 0.0, 1e-15, -1e-15])
    alpha = first_volume_crossing(b, c, d, ETA)
    np.testing.assert_allclose(alpha[:2], 1.0)
    np.testing.assert_allclose(alpha[2], 0.5, atol=1e-14)  # g0 - 2 g0 alpha
    np.testing.assert_allclose(alpha[3], 0.5, atol=1e-14)  # g0 - 4 g0 alpha^2
    np.testing.assert_allclose(alpha[4:], g0, atol=1e-13)  # g0 - alpha (+ 1e-15 alpha^3)
    # a double root (the ratio touches eta at alpha = 0.5 and grows again)
    touch = first_volume_crossing(np.array([-4.0 * g0]), np.array([4.0 * g0]), np.array([0.0]), ETA)
    np.testing.assert_allclose(touch, 0.5, atol=1e-7)
    # the ratio dips below eta between two samples and comes back: the first crossing counts
    r1, r2 = 0.3, 0.31  # g = g0 (1 - a/r1)(1 - a/r2)(1 + a)
    b3 = g0 * (1.0 - 1.0 / r1 - 1.0 / r2)
    c3 = g0 * (1.0 / (r1 * r2) - 1.0 / r1 - 1.0 / r2)
    d3 = g0 / (r1 * r2)
    dip = first_volume_crossing(np.array([b3]), np.array([c3]), np.array([d3]), ETA)
    np.testing.assert_allclose(dip, r1, atol=1e-12)
    # non-finite coefficients (a degenerate current cell) are left to the J check
    assert first_volume_crossing(np.array([np.nan]), np.array([0.0]), np.array([np.inf]), ETA)[0] == 1.0
    with pytest.raises(ParameterError, match="volume_fraction"):
        first_volume_crossing(b, c, d, 1.0)


# -- on meshes -----------------------------------------------------------------------------------
def _mesh(comm, d):
    if d == 2:
        return dmesh.create_unit_square(comm, 5, 4, diagonal=dmesh.DiagonalType.crossed)
    return dmesh.create_box(comm, [[0.0, 0.0, 0.0], [1.0, 0.7, 0.5]], [3, 3, 2])


def _field(V, seed, amplitude):
    """A smooth 'random' vector field, defined by coordinates (the same on any partition)."""
    rng = np.random.default_rng(seed)
    d = V.mesh.geometry.dim
    k, phase = rng.uniform(1.0, 6.0, (d, 3)), rng.uniform(0.0, 6.3, (d, 3))
    f = fem.Function(V)
    f.interpolate(lambda x: amplitude * np.array([np.sin(k[i] @ x + phase[i].sum()) for i in range(d)]))
    return f


def _cell_J(w):
    """J = det(I + grad w) per owned cell, by DOLFINx (P1: constant per cell)."""
    m = w.function_space.mesh
    d = m.geometry.dim
    tdim = m.topology.dim
    point = np.full((1, tdim), 1.0 / (tdim + 1))
    expr = fem.Expression(ufl.det(ufl.Identity(d) + ufl.grad(w)), point)
    cells = np.arange(m.topology.index_map(tdim).size_local, dtype=np.int32)
    return expr.eval(m, cells).reshape(-1)


@pytest.mark.parametrize("d", [2, 3])
def test_filtered_steps_never_invert_and_are_partition_independent(comm, d):
    msh = _mesh(comm, d)
    V = fem.functionspace(msh, ("Lagrange", 1, (d,)))
    step_filter = StepFilter(V, ETA)
    u = _field(V, 0, 0.05)
    Vs = fem.functionspace(_mesh(MPI.COMM_SELF, d), ("Lagrange", 1, (d,)))
    serial = StepFilter(Vs, ETA)
    us = _field(Vs, 0, 0.05)
    limited = 0
    for seed, amplitude in [(1, 0.02), (2, 0.3), (3, 1.0), (4, 3.0), (5, 10.0)]:
        p = _field(V, seed, amplitude)
        alpha = step_filter.max_step(u.x.array, p.x.array)
        assert 0.0 < alpha <= 1.0
        # the same alpha from the whole mesh on one rank
        alpha_serial = serial.max_step(us.x.array, _field(Vs, seed, amplitude).x.array)
        assert alpha == pytest.approx(alpha_serial, rel=1e-12)
        assert comm.allgather(alpha) == [alpha] * comm.size
        J0 = _cell_J(u)
        w = fem.Function(V)
        w.x.array[:] = u.x.array + alpha * p.x.array
        ratio = _cell_J(w) / J0
        low = comm.allreduce(ratio.min() if ratio.size else np.inf, op=MPI.MIN)
        assert low >= ETA - 1e-9  # no cell below eta of its volume, so none inverted
        if alpha < 1.0:
            limited += 1
            assert low == pytest.approx(ETA, abs=1e-8)  # and the step is the largest such
            w.x.array[:] = u.x.array + min(1.0, alpha * (1 + 1e-4)) * p.x.array
            assert comm.allreduce(np.min(_cell_J(w) / J0, initial=np.inf), op=MPI.MIN) < ETA
    assert limited >= 3


def test_alpha_is_one_when_no_cell_shrinks_below_eta(comm):
    msh = _mesh(comm, 3)
    V = fem.functionspace(msh, ("Lagrange", 1, (3,)))
    step_filter = StepFilter(V, ETA)
    zero = np.zeros_like(fem.Function(V).x.array)
    X = fem.Function(V)
    X.interpolate(lambda x: x)
    # growth, a rigid translation, a shrink to (1 - 0.5)^3 = 0.125 > eta of the volume
    assert step_filter.max_step(zero, 2.0 * X.x.array) == 1.0
    assert step_filter.max_step(zero, np.tile([1.0, -2.0, 0.5], len(zero) // 3)) == 1.0
    assert step_filter.max_step(zero, -0.5 * X.x.array) == 1.0
    # a shrink past it: (1 - s alpha)^3 = eta
    assert step_filter.max_step(zero, -0.8 * X.x.array) == pytest.approx((1 - ETA ** (1 / 3)) / 0.8, rel=1e-12)


def test_applicability():
    comm = MPI.COMM_WORLD
    msh = _mesh(comm, 3)
    assert exact_filter_applies(fem.functionspace(msh, ("Lagrange", 1, (3,))))
    assert not exact_filter_applies(fem.functionspace(msh, ("Lagrange", 2, (3,))))
    assert not exact_filter_applies(fem.functionspace(msh, ("Lagrange", 1)))
    hexes = dmesh.create_unit_cube(comm, 1, 1, 1, dmesh.CellType.hexahedron)
    assert not exact_filter_applies(fem.functionspace(hexes, ("Lagrange", 1, (3,))))
    with pytest.raises(ParameterError, match="P1 vector displacement"):
        StepFilter(fem.functionspace(msh, ("Lagrange", 2, (3,))))
    with pytest.raises(ParameterError, match="volume_fraction"):
        StepFilter(fem.functionspace(msh, ("Lagrange", 1, (3,))), 0.0)


# -- in the Newton solver ------------------------------------------------------------------------
def _bend(scale=1.0, degree=1):
    domain = hf.read_mesh(MESH)
    params = CantileverSpec().lame
    return hf.HyperelasticProblem(
        domain,
        lambda F: hf.materials.neo_hookean(F, params),
        bcs=[hf.Clamp("clamped")],
        loads=[bend_load(scale)],
        degree=degree,
    )


def test_precheck_scales_the_step_to_the_exact_fraction():
    """Trial state -2X (F = -I) from 0: the volume ratio along the step is (1 - 2 alpha)^3."""
    problem = _bend()
    solver = hf.NewtonSolver(problem)
    assert solver.step_filter == "exact"
    x = solver._nlp.x
    x.set(0.0)
    trial = problem.u.copy()
    trial.interpolate(lambda X: -2.0 * X)
    y = x.duplicate()
    y.array[:] = -trial.x.array[: y.getLocalSize()]
    solver._precheck(x, y)
    alpha = STEP_SAFETY * (1.0 - ETA ** (1.0 / 3.0)) / 2.0
    assert solver.filtered_steps == 1 and solver.inversion_cutbacks == 0
    problem.u.x.array[: y.getLocalSize()] = -y.array
    problem.u.x.scatter_forward()
    assert solver.min_J() == pytest.approx((1.0 - 2.0 * alpha) ** 3, rel=1e-10)


def test_newton_with_exact_filter_converges_to_the_bisection_solution():
    """20x the bend load in one step: Newton's first direction would invert cells."""
    results = {}
    for step_filter in ("exact", "bisection"):
        problem = _bend(scale=20.0)
        solver = hf.NewtonSolver(problem, step_filter=step_filter)
        problem.set_time(1.0)
        record = solver.solve(raise_on_failure=True)
        assert record.step_filter == step_filter
        assert record.min_J > 0.1
        results[step_filter] = (record, PointProbe(problem.domain.mesh, [TEST_POINT])(problem.u)[0])
    exact, bisection = results["exact"][0], results["bisection"][0]
    assert exact.filtered_steps >= 1 and exact.inversion_cutbacks == 0 and exact.min_step_fraction < 1.0
    assert bisection.inversion_cutbacks >= 1 and bisection.filtered_steps == 0
    u_exact, u_bisection = results["exact"][1], results["bisection"][1]
    assert np.linalg.norm(u_bisection) > 5.0  # a large deflection (the beam is 10 m long)
    np.testing.assert_allclose(u_exact, u_bisection, rtol=1e-7, atol=1e-8)


def test_guard_options():
    problem = _bend()
    assert hf.NewtonSolver(problem).min_jacobian == 1e-6
    assert hf.NewtonSolver(problem, step_filter="bisection").step_filter == "bisection"
    unguarded = hf.NewtonSolver(problem, min_jacobian=None)
    assert unguarded.step_filter == "none"
    assert hf.NewtonSolver(problem, min_jacobian=None, step_filter="exact").step_filter == "exact"
    problem.invertible = True  # what an invertible material's problem says (seed 004: no filtering needed)
    solver = hf.NewtonSolver(problem)
    assert solver.min_jacobian is None and solver.step_filter == "none"
    assert hf.NewtonSolver(problem, min_jacobian=1e-3).step_filter == "exact"
    with pytest.raises(ParameterError, match="step_filter must be one of"):
        hf.NewtonSolver(problem, step_filter="cubic")
    with pytest.raises(ParameterError, match="min_jacobian"):
        hf.NewtonSolver(problem, min_jacobian="never")
    with pytest.raises(ParameterError, match="volume_fraction"):
        hf.NewtonSolver(problem, min_jacobian=1e-6, volume_fraction=1.5)
    p2 = _bend(degree=2)
    assert hf.NewtonSolver(p2).step_filter == "bisection"
    with pytest.raises(ParameterError, match="step_filter='exact' needs"):
        hf.NewtonSolver(p2, step_filter="exact")
