r"""Projected Newton (seed 004): the PSD-projected material tangent and the solver built on it.

Closed form used throughout: for the compressible Neo-Hookean law and
:math:`F = R\,\operatorname{diag}(\sigma)\,V^T`, the :math:`d^2` eigenvalues of
:math:`\partial^2\psi/\partial F^2` are those of the Hessian of
:math:`\hat\psi(\sigma)`,

.. math::
    \hat H_{ij} = \delta_{ij}\Bigl(\mu + \frac{c}{\sigma_i^2}\Bigr) + \frac{\lambda}{\sigma_i\sigma_j},
    \qquad c = \mu - \lambda\ln J,

and, per pair :math:`i < j`, :math:`(\hat\psi_i \mp \hat\psi_j)/(\sigma_i \mp \sigma_j)
= \mu \pm c/(\sigma_i\sigma_j)` (seed 004, "diagonal space"). Under lateral
compression :math:`\mu - c/(\sigma_i\sigma_j) < 0`: the tangent is indefinite
at a perfectly stable homogeneous state.
"""

from __future__ import annotations

from itertools import combinations
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem.petsc import assemble_matrix

import hyperfem as hf
from hyperfem.cases import CantileverSpec, bend_load, twist_load
from hyperfem.cases.uniaxial import unit_cube
from hyperfem.errors import ParameterError
from hyperfem.solver.projected import ProjectedTangent, project_psd, projected_newton_solver

MESHES = Path(__file__).resolve().parent.parent / "meshes"
PARAMS = hf.materials.LameParameters.from_youngs(1.0, 0.3)


def nh(params=PARAMS):
    return lambda F: hf.materials.neo_hookean(F, params)


def nh_spectrum(sigma, params=PARAMS) -> np.ndarray:
    """Sorted eigenvalues of the Neo-Hookean material tangent at principal stretches ``sigma``."""
    s = np.asarray(sigma, dtype=float)
    mu, lmbda = params.mu, params.lmbda
    c = mu - lmbda * np.log(np.prod(s))
    H = np.diag(mu + c / s**2) + lmbda * np.outer(1 / s, 1 / s)
    eig = list(np.linalg.eigvalsh(H))
    for i, j in combinations(range(len(s)), 2):
        eig += [mu + c / (s[i] * s[j]), mu - c / (s[i] * s[j])]
    return np.sort(eig)


def rotation(d: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    if d == 2:
        return np.array([[c, -s], [s, c]])
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    W = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + s * W + (1 - c) * W @ W


def homogeneous_gradient(sigma) -> np.ndarray:
    d = len(sigma)
    return rotation(d, 0.7) @ np.diag(sigma) @ rotation(d, -0.4).T


def set_homogeneous(problem, F: np.ndarray) -> None:
    d = F.shape[0]
    problem.u.interpolate(lambda x: (F - np.eye(d)) @ x[:d])


def unit_square(n: int = 2) -> hf.Domain:
    mesh = dmesh.create_unit_square(MPI.COMM_WORLD, n, n)
    return hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)}, source=f"unit_square({n})")


def field_spectra(tangent: ProjectedTangent) -> list[np.ndarray]:
    """Sorted eigenvalues of the stored field at every owned quadrature point, per material integral."""
    d2 = tangent._d**2
    out = []
    for term in tangent._terms:
        values = term.field.x.array.reshape(-1, d2, d2)[term.dofs.reshape(-1)]
        out.append(np.linalg.eigvalsh(values))
    return out


def field_values(tangent: ProjectedTangent) -> list[np.ndarray]:
    d2 = tangent._d**2
    return [t.field.x.array.reshape(-1, d2, d2)[t.dofs.reshape(-1)].copy() for t in tangent._terms]


def all_ranks(flag: bool) -> bool:
    return bool(MPI.COMM_WORLD.allreduce(bool(flag), op=MPI.LAND))


def relative_difference(a_form, b_form, bcs=()) -> float:
    """:math:`\\|A - B\\|_F / \\|A\\|_F` of two assembled bilinear forms (PETSc, any number of ranks)."""
    A = assemble_matrix(fem.form(a_form), bcs=list(bcs))
    A.assemble()
    B = assemble_matrix(fem.form(b_form), bcs=list(bcs))
    B.assemble()
    scale = A.norm()
    B.axpy(-1.0, A)
    value = B.norm() / scale
    A.destroy()
    B.destroy()
    return value


# -- the per-point projection --------------------------------------------------------------
def test_project_psd_closed_forms():
    A = np.array([[[-1.0, 0.0], [0.0, 2.0]], [[1.0, 3.0], [1.0, 1.0]]])  # second: sym = [[1, 2], [2, 1]], eig -1, 3
    clamp, smallest, changed = project_psd(A)
    np.testing.assert_allclose(clamp[0], np.diag([0.0, 2.0]), atol=1e-15)
    np.testing.assert_allclose(clamp[1], 1.5 * np.ones((2, 2)), atol=1e-14)  # 3 v v^T, v = (1, 1)/sqrt 2
    np.testing.assert_allclose(smallest, [-1.0, -1.0], atol=1e-14)
    assert changed.tolist() == [True, True]
    flipped, _, _ = project_psd(A, mode="abs")
    np.testing.assert_allclose(flipped[0], np.diag([1.0, 2.0]), atol=1e-15)
    np.testing.assert_allclose(flipped[1], [[2.0, 1.0], [1.0, 2.0]], atol=1e-14)  # |eig| = 1, 3
    floored, _, changed = project_psd(np.array([np.diag([2.0, 1e-3])]), floor=0.01)
    np.testing.assert_allclose(floored[0], np.diag([2.0, 0.02]), atol=1e-15)  # raised to 1 % of the largest
    assert changed.tolist() == [True]


def test_project_psd_is_psd_and_keeps_psd_matrices():
    rng = np.random.default_rng(3)
    M = rng.standard_normal((400, 9, 9))
    psd = M[:200] @ np.swapaxes(M[:200], 1, 2)  # PSD (rank 9, some nearly singular)
    stack = np.concatenate([psd, M[200:]])
    out, smallest, changed = project_psd(stack)
    lam = np.linalg.eigvalsh(out)
    assert lam.min() >= -1e-12 * np.abs(lam).max()
    sym = 0.5 * (stack + np.swapaxes(stack, 1, 2))
    kept = ~changed
    assert kept[:200].all() and changed[200:].sum() >= 190  # random symmetric 9x9: almost all indefinite
    np.testing.assert_array_equal(out[kept], sym[kept])  # untouched: no reconstruction round-off
    # what the projection removes is exactly the negative part: sym = A+ - A-, A- PSD, A+ A- = 0
    negative = out[changed] - sym[changed]
    assert np.linalg.eigvalsh(negative).min() >= -1e-10 * np.abs(sym).max()
    np.testing.assert_allclose(np.einsum("nij,njk->nik", out[changed], negative), 0.0, atol=1e-9)
    np.testing.assert_allclose(smallest, np.linalg.eigvalsh(sym)[:, 0], rtol=1e-10, atol=1e-12)


def test_project_psd_passes_nonfinite_through_and_checks_input():
    A = np.stack([np.diag([-1.0, 1.0]), np.full((2, 2), np.nan)])
    out, smallest, changed = project_psd(A)
    np.testing.assert_allclose(out[0], np.diag([0.0, 1.0]), atol=1e-15)
    assert np.isnan(out[1]).all() and np.isnan(smallest[1]) and not changed[1]
    with pytest.raises(ParameterError, match="shape"):
        project_psd(np.zeros((3, 2, 3)))
    with pytest.raises(ParameterError, match="floor"):
        project_psd(A, floor=1.0)
    with pytest.raises(ParameterError, match="mode"):
        project_psd(A, mode="flip")


# -- the quadrature fields ---------------------------------------------------------------------
@pytest.mark.parametrize(
    "sigma",
    [(1.2, 0.9, 0.95), (1.1, 0.85)],  # 3D and 2D (plane strain), each with a compressed pair
    ids=["3d", "2d"],
)
def test_material_tangent_spectrum_matches_closed_form(sigma):
    domain = unit_cube(1) if len(sigma) == 3 else unit_square(2)
    problem = hf.HyperelasticProblem(domain, nh(), degree=2)  # several quadrature points per cell
    set_homogeneous(problem, homogeneous_gradient(sigma))
    tangent = ProjectedTangent(problem)
    exact = nh_spectrum(sigma)
    assert exact[0] < -0.01 * exact[-1]  # the closed form says: indefinite

    tangent.active = False  # consistent: the stored field is sym(A)
    tangent.refresh()
    for lam in field_spectra(tangent):
        np.testing.assert_allclose(lam, np.broadcast_to(exact, lam.shape), rtol=1e-10, atol=1e-12)

    tangent.active = True
    tangent.refresh()
    for lam in field_spectra(tangent):
        np.testing.assert_allclose(lam, np.broadcast_to(np.maximum(exact, 0.0), lam.shape), atol=1e-12)
    stats = tangent.statistics()
    assert stats.points > 0 and stats.projected == stats.points and stats.nonfinite == 0
    np.testing.assert_allclose(stats.min_eigenvalue, exact[0], rtol=1e-10)


def test_projected_equals_consistent_where_psd():
    domain = unit_cube(2)
    # Neo-Hookean at rest: A is PSD (zero modes = rotations), so K+ = K.
    problem = hf.HyperelasticProblem(domain, nh(), degree=1)
    tangent = ProjectedTangent(problem)
    tangent.refresh()
    assert tangent.statistics().projected == 0
    assert relative_difference(problem.jacobian, tangent.form) < 1e-13

    # Small-strain linear elasticity: A is constant and PSD at any state, so K+ = K anywhere.
    linear = hf.HyperelasticProblem(domain, lambda F: hf.materials.linear_elastic(F, PARAMS), degree=1)
    set_homogeneous(linear, homogeneous_gradient((1.3, 0.8, 0.9)))
    linear_tangent = ProjectedTangent(linear)
    linear_tangent.refresh()
    assert linear_tangent.statistics().projected == 0
    assert relative_difference(linear.jacobian, linear_tangent.form) < 1e-13

    # Neo-Hookean at a smooth non-homogeneous state: pointwise, A+ = sym(A) exactly where
    # sym(A) is PSD, and A+ is PSD everywhere.
    problem.u.interpolate(lambda x: np.stack([0.3 * x[0] ** 2 - 0.2 * x[0], -0.25 * x[0] * x[1], 0.2 * np.sin(x[2])]))
    tangent.active = False
    tangent.refresh()
    (consistent,) = field_values(tangent)
    # unprojected, the fields reproduce the consistent tangent point by point (layout check)
    assert relative_difference(problem.jacobian, tangent.form) < 1e-12
    tangent.active = True
    tangent.refresh()
    (projected,) = field_values(tangent)
    lam = np.linalg.eigvalsh(consistent)
    psd = lam[:, 0] >= -1e-12 * np.abs(lam).max(axis=1)
    np.testing.assert_array_equal(projected[psd], consistent[psd])
    lam_plus = np.linalg.eigvalsh(projected)
    assert all_ranks(lam_plus.size == 0 or lam_plus.min() >= -1e-12 * np.abs(lam_plus).max())
    stats = tangent.statistics()
    assert 0 < stats.projected < stats.points  # both kinds of point occur
    assert stats.projected == MPI.COMM_WORLD.allreduce(int((~psd).sum()), op=MPI.SUM)


@pytest.mark.serial
def test_assembled_projected_tangent_is_psd_where_the_consistent_one_is_not():
    problem = hf.HyperelasticProblem(unit_cube(2), nh(), degree=1)
    set_homogeneous(problem, homogeneous_gradient((1.0, 0.8, 0.8)))  # laterally squeezed
    tangent = ProjectedTangent(problem)
    tangent.refresh()

    def spectrum(form):
        K = fem.assemble_matrix(fem.form(form)).to_dense()
        return np.linalg.eigvalsh(0.5 * (K + K.T))

    K_lam, Kp_lam = spectrum(problem.jacobian), spectrum(tangent.form)
    assert K_lam.min() < -1e-3 * K_lam.max()  # consistent tangent: indefinite (no BCs: rigid modes aside)
    assert Kp_lam.min() >= -1e-12 * Kp_lam.max()


def test_multi_region_fields_follow_their_own_material():
    mesh = dmesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2)
    tdim = mesh.topology.dim
    n = mesh.topology.index_map(tdim).size_local + mesh.topology.index_map(tdim).num_ghosts
    cells = np.arange(n, dtype=np.int32)
    midpoints = dmesh.compute_midpoints(mesh, tdim, cells)
    tags = dmesh.meshtags(mesh, tdim, cells, np.where(midpoints[:, 0] < 0.5, 1, 2).astype(np.int32))
    domain = hf.Domain(mesh, cell_tags=tags, cell_groups={"soft": 1, "stiff": 2}, source="two-region cube")
    stiff = hf.materials.LameParameters.from_youngs(10.0, 0.45)
    problem = hf.HyperelasticProblem(domain, {"soft": nh(), "stiff": nh(stiff)}, degree=1)
    sigma = (1.15, 0.9, 0.9)
    set_homogeneous(problem, homogeneous_gradient(sigma))
    tangent = ProjectedTangent(problem)
    assert len(tangent.fields) == 2
    tangent.active = False
    tangent.refresh()
    for term, lam in zip(tangent._terms, field_spectra(tangent), strict=True):
        which = tags.values[term.cells]
        assert np.unique(which).size <= 1  # one region per material integral
        params = PARAMS if which.size == 0 or which[0] == 1 else stiff
        np.testing.assert_allclose(lam, np.broadcast_to(nh_spectrum(sigma, params), lam.shape), rtol=1e-10, atol=1e-10)
    covered = MPI.COMM_WORLD.allreduce(sum(t.cells.size for t in tangent._terms), op=MPI.SUM)
    assert covered == MPI.COMM_WORLD.allreduce(mesh.topology.index_map(tdim).size_local, op=MPI.SUM)


def test_refresh_recomputes_only_when_the_state_changes():
    domain = unit_cube(1)
    scale = fem.Constant(domain.mesh, 1.0)
    problem = hf.HyperelasticProblem(domain, lambda F: scale * hf.materials.neo_hookean(F, PARAMS))
    set_homogeneous(problem, homogeneous_gradient((1.2, 0.9, 0.95)))
    tangent = ProjectedTangent(problem)
    tangent()
    tangent()
    assert tangent.refreshes == 1  # same state: skipped
    (before,) = field_values(tangent)
    scale.value = 2.0  # a material constant changed, u did not
    tangent()
    assert tangent.refreshes == 2
    (after,) = field_values(tangent)
    np.testing.assert_allclose(after, 2.0 * before, rtol=1e-12, atol=1e-14)
    problem.u.x.array[:] *= 0.5
    tangent()
    tangent.refresh(force=True)
    assert tangent.refreshes == 4


# -- the solver --------------------------------------------------------------------------------
def _beam(load):
    domain = hf.read_mesh(MESHES / "beam_h2.msh")
    problem = hf.HyperelasticProblem(domain, nh(CantileverSpec().lame), bcs=[hf.Clamp("clamped")], loads=[load])
    problem.set_time(1.0)
    return problem


@pytest.mark.parametrize("case", ["bend", "twist"])
def test_projected_newton_converges_to_the_plain_newton_solution(case):
    """Same residual, other tangent: the same equilibrium (twist: with the follower-load tangent)."""
    load = bend_load() if case == "bend" else twist_load()
    tight = {"snes_rtol": 1e-11, "snes_atol": 1e-12, "snes_max_it": 80}
    reference = _beam(load)
    plain = hf.NewtonSolver(reference, tight).solve(raise_on_failure=True)
    scale = np.abs(reference.u.x.array).max()

    problem = _beam(load)
    tangent = ProjectedTangent(problem)
    record = projected_newton_solver(problem, tight, tangent=tangent).solve(raise_on_failure=True)
    assert record.converged and tangent.active
    stats = tangent.statistics()
    assert stats.projected > 0  # the solution has indefinite points: K+ != K there
    assert record.iterations > plain.iterations  # ... so the convergence is linear (measured 8-16 vs 4-6)
    assert all_ranks(np.abs(problem.u.x.array - reference.u.x.array).max() <= 1e-8 * scale)

    hybrid_problem = _beam(load)
    hybrid_tangent = ProjectedTangent(hybrid_problem)
    hybrid = projected_newton_solver(hybrid_problem, tight, tangent=hybrid_tangent, consistent_below=1e-2)
    hybrid.solve(raise_on_failure=True)
    assert not hybrid_tangent.active  # switched to the consistent tangent near the solution
    assert all_ranks(np.abs(hybrid_problem.u.x.array - reference.u.x.array).max() <= 1e-8 * scale)


def test_errors():
    domain = unit_cube(1)
    problem = hf.HyperelasticProblem(domain, nh())
    with pytest.raises(ParameterError, match="floor"):
        ProjectedTangent(problem, floor=-0.1)
    with pytest.raises(ParameterError, match="mode"):
        ProjectedTangent(problem, mode="negate")
    with pytest.raises(ParameterError, match="jacobian"):
        projected_newton_solver(problem, jacobian=problem.jacobian)
    with pytest.raises(ParameterError, match="consistent_below"):
        projected_newton_solver(problem, consistent_below=1.0)
    other = hf.HyperelasticProblem(unit_cube(1), nh())
    with pytest.raises(ParameterError, match="another problem"):
        projected_newton_solver(problem, tangent=ProjectedTangent(other))
    split = hf.problem.mixed.SplitEnergy(lambda F: hf.materials.neo_hookean(F, PARAMS), 1.0)
    mixed = hf.problem.mixed.MixedHyperelasticProblem(domain, split)
    with pytest.raises(ParameterError, match="displacement problem"):
        ProjectedTangent(mixed)
    # an energy that depends on u itself, not only on grad(u)
    u_dependent = hf.HyperelasticProblem(domain, nh())
    u = u_dependent.u
    u_dependent.energy_internal = u_dependent.energy_internal + ufl.dot(u, u) * ufl.dx(
        metadata={"quadrature_degree": 1}
    )
    with pytest.raises(ParameterError, match="other than through grad"):
        ProjectedTangent(u_dependent)
