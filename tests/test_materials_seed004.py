r"""The materials of seed 004: polar SVD, stable Neo-Hookean, fixed-corotated, ARAP, COR.

* Polar decomposition (NumPy): proper rotation, symmetric stretch, the sign
  fix of Algorithm 6 for inverted F, agreement with independent references,
  :math:`\partial R/\partial F` against finite differences.
* Every material, evaluated with :class:`dolfinx.fem.Expression` on a
  one-cell mesh (``MPI.COMM_SELF``) with :math:`F = I + \nabla u` for an
  affine ``u`` (constant :math:`F`; rotation fields refreshed from it):
  rest state, tangent at :math:`I` = linear elasticity, UFL stress = closed
  form (and an independent NumPy formula), stress = finite differences of
  the energy, tangent = finite differences of the stress, objectivity,
  finite energy for inverted F.
* On a small box (``MPI.COMM_WORLD``): Taylor tests of energy, residual and
  tangent of the fixed-corotated problem with the rotation refreshed at each
  state (exact tangent: second order; frozen-R tangent: first order), and
  the patch test solved by :class:`~hyperfem.solver.NewtonSolver` through the
  problem's ``state_hooks``.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.errors import ParameterError
from hyperfem.materials import (
    ARAP,
    CorotationalLinear,
    FixedCorotated,
    LameParameters,
    QuadratureField,
    StableNeoHookeanParameters,
    corotational_linear,
    polar_decomposition,
    polar_rotation,
    polar_svd,
    rotation_derivative,
    stable_neo_hookean,
    stable_neo_hookean_stress,
)

PARAMS = LameParameters(mu=3.7, lmbda=11.3)
JIT_OPTIONS = {"timeout": 300}
MATERIALS = ["stable_neo_hookean", "fixed_corotated", "arap", "corotational"]


# --------------------------------------------------------------------------
# NumPy references
# --------------------------------------------------------------------------
def random_F(rng, dim, scale=0.3, min_det=0.2):
    while True:
        F = np.eye(dim) + scale * rng.standard_normal((dim, dim))
        if np.linalg.det(F) > min_det:
            return F


def random_rotation(rng, dim):
    while True:
        Q, R = np.linalg.qr(rng.standard_normal((dim, dim)))
        Q = Q @ np.diag(np.sign(np.diag(R)))
        if np.linalg.det(Q) < 0:
            Q[:, 0] *= -1
        if np.linalg.norm(Q - np.eye(dim)) > 0.5:
            return Q


def inverted_F(dim):
    F = np.eye(dim)
    F[0, 0] = -0.6
    F[1, 0] = 0.25
    F[0, 1] = -0.1
    return F


def reference_rotation(F):
    """Closest proper rotation without the sign-fix code: R = F C^{-1/2} (det F > 0) or Kabsch."""
    if np.linalg.det(F) > 0:
        w, Q = np.linalg.eigh(F.T @ F)
        return F @ Q @ np.diag(w**-0.5) @ Q.T
    U, _, Vt = np.linalg.svd(F)
    D = np.eye(F.shape[0])
    D[-1, -1] = np.linalg.det(U @ Vt)
    return U @ D @ Vt


def cofactor_np(F):
    return np.linalg.det(F) * np.linalg.inv(F).T


def linear_tensor(mu, lam, dim):
    """d^2 psi_lin / dF dF: mu (d_ik d_jl + d_il d_jk) + lam d_ij d_kl."""
    eye = np.eye(dim)
    return (
        mu * (np.einsum("ik,jl->ijkl", eye, eye) + np.einsum("il,jk->ijkl", eye, eye))
        + lam * np.einsum("ij,kl->ijkl", eye, eye)
    )


def closed_form_np(name, F, R=None):
    """psi and P of each law in NumPy (R: the rotation to use; default the polar rotation of F)."""
    mu, lam = PARAMS.mu, PARAMS.lmbda
    d = F.shape[0]
    R = reference_rotation(F) if R is None else R
    J = np.linalg.det(F)
    if name == "stable_neo_hookean":
        c = StableNeoHookeanParameters.from_lame(PARAMS)
        IC = np.sum(F * F) + (3 - d)  # plane strain in 2D
        psi = 0.5 * c.mu * (IC - 3) + 0.5 * c.lmbda * (J - c.alpha) ** 2 - 0.5 * c.mu * np.log(IC + 1) - c.rest_offset
        P = c.mu * (1 - 1 / (IC + 1)) * F + c.lmbda * (J - c.alpha) * cofactor_np(F)
    elif name == "fixed_corotated":
        psi = mu * np.sum((F - R) ** 2) + 0.5 * lam * (J - 1) ** 2
        P = 2 * mu * (F - R) + lam * (J - 1) * cofactor_np(F)
    elif name == "arap":
        psi = mu * np.sum((F - R) ** 2)
        P = 2 * mu * (F - R)
    else:
        G = R.T @ F
        eps = 0.5 * (G + G.T) - np.eye(d)
        psi = mu * np.sum(eps * eps) + 0.5 * lam * np.trace(eps) ** 2
        P = R @ (2 * mu * eps + lam * np.trace(eps) * np.eye(d))
    return psi, P


# --------------------------------------------------------------------------
# Polar decomposition
# --------------------------------------------------------------------------
def _sample(dim, n=40, seed=3):
    rng = np.random.default_rng(seed + dim)
    F = np.eye(dim) + 0.6 * rng.standard_normal((n, dim, dim))
    F[: n // 3] = F[: n // 3] @ np.diag([-1.0] + [1.0] * (dim - 1))  # a third mirrored
    F[0] = inverted_F(dim)
    return F


@pytest.mark.parametrize("dim", [2, 3])
def test_polar_is_a_proper_rotation_times_a_symmetric_stretch(dim):
    F = _sample(dim)
    R, S = polar_decomposition(F)
    eye = np.broadcast_to(np.eye(dim), R.shape)
    np.testing.assert_allclose(np.swapaxes(R, 1, 2) @ R, eye, atol=1e-13)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-13)
    np.testing.assert_allclose(R @ S, F, atol=1e-13)
    np.testing.assert_allclose(S, np.swapaxes(S, 1, 2), atol=1e-15)
    # Sign fix: sign(sigma_d) = sign(det F); S has exactly one negative eigenvalue when inverted.
    detF = np.linalg.det(F)
    assert np.any(detF < 0) and np.any(detF > 0)
    _, sigma, _ = polar_svd(F)
    np.testing.assert_array_equal(np.sign(sigma[:, -1]), np.sign(detF))
    assert np.all(sigma[:, :-1] >= np.abs(sigma[:, -1:]) - 1e-14)
    negative = np.sum(np.linalg.eigvalsh(S) < 0, axis=1)
    np.testing.assert_array_equal(negative, (detF < 0).astype(int))


@pytest.mark.parametrize("dim", [2, 3])
def test_polar_matches_independent_references(dim):
    """R = F (F^T F)^{-1/2} for det F > 0; Kabsch (SVD + det fix) otherwise; R is the closest rotation."""
    F = _sample(dim)
    R = polar_rotation(F)
    for Fi, Ri in zip(F, R, strict=True):
        np.testing.assert_allclose(Ri, reference_rotation(Fi), atol=1e-11)
    rng = np.random.default_rng(8)
    for Fi, Ri in zip(F[:10], R[:10], strict=True):
        best = np.sum((Fi - Ri) ** 2)
        for _ in range(20):
            Q = random_rotation(rng, dim)
            assert np.sum((Fi - Q) ** 2) >= best - 1e-12
    # A pure rotation is its own polar rotation with S = I.
    Q = random_rotation(rng, dim)
    Rq, Sq = polar_decomposition(Q[None])
    np.testing.assert_allclose(Rq[0], Q, atol=1e-13)
    np.testing.assert_allclose(Sq[0], np.eye(dim), atol=1e-13)


@pytest.mark.parametrize("dim", [2, 3])
def test_rotation_derivative(dim):
    """T = dR/dF matches central differences; kills dF = R dS (dS symmetric); symmetric; skew projector at I."""
    F = _sample(dim, n=12)
    F = F[np.min(np.abs(polar_svd(F)[1]), axis=1) > 0.05]  # away from sigma_i + sigma_j = 0
    U, sigma, V = polar_svd(F)
    T = rotation_derivative(U, sigma, V)
    h = 1e-6
    fd = np.zeros_like(T)
    for k in range(dim):
        for l in range(dim):  # noqa: E741
            dF = np.zeros((dim, dim))
            dF[k, l] = h
            fd[..., k, l] = (polar_rotation(F + dF) - polar_rotation(F - dF)) / (2 * h)
    np.testing.assert_allclose(T, fd, atol=1e-7 * np.abs(T).max())
    np.testing.assert_allclose(T, np.einsum("nijkl->nklij", T), atol=1e-14)
    R = U @ np.swapaxes(V, 1, 2)
    rng = np.random.default_rng(2)
    dS = rng.standard_normal((len(F), dim, dim))
    dS = dS + np.swapaxes(dS, 1, 2)
    np.testing.assert_allclose(np.einsum("nijkl,nkl->nij", T, R @ dS), 0.0, atol=1e-12)
    U0, s0, V0 = polar_svd(np.eye(dim)[None])
    T0 = rotation_derivative(U0, s0, V0)[0]
    eye = np.eye(dim)
    skew = 0.5 * (np.einsum("ik,jl->ijkl", eye, eye) - np.einsum("il,jk->ijkl", eye, eye))
    np.testing.assert_allclose(T0, skew, atol=1e-14)


def test_polar_rejects_bad_shapes():
    with pytest.raises(ParameterError, match="polar_svd"):
        polar_svd(np.zeros((4, 3, 2)))


def test_quadrature_field_order_matches_interpolation(comm):
    """evaluate/assign use the dof order of the quadrature space (checked against Function.interpolate)."""
    mesh = dmesh.create_unit_cube(comm, 2, 2, 1)
    V = fem.functionspace(mesh, ("Lagrange", 2, (3,)))
    u = fem.Function(V)
    u.interpolate(lambda x: np.array([x[0] * x[1], np.sin(x[2]) + x[0] ** 2, x[1] * x[2]]))
    F = ufl.Identity(3) + ufl.grad(u)
    field = QuadratureField(mesh, 2, (3, 3))
    expr = field.expression(F, jit_options=JIT_OPTIONS)
    values = field.evaluate(expr)
    assert values.shape == (field.num_cells * field.num_points, 3, 3)
    field.assign(values)
    reference = fem.Function(field.space)
    reference.interpolate(expr)
    n = field.space.dofmap.index_map.size_local * field.space.dofmap.index_map_bs
    np.testing.assert_allclose(field.function.x.array[:n], reference.x.array[:n], atol=1e-13)
    np.testing.assert_allclose(field.values(), values, atol=0)
    with pytest.raises(ParameterError, match="shape"):
        field.assign(values[:-1])


# --------------------------------------------------------------------------
# Materials at a point
# --------------------------------------------------------------------------
class _Point:
    """psi, P (UFL), P (closed form), frozen-field tangent and tangent correction at a constant F.

    ``F = I + grad u`` for an affine P1 ``u`` on a one-cell mesh; rotation
    fields are refreshed from it (COR: only when asked, R^n is a step quantity).
    """

    def __init__(self, name: str, dim: int):
        self.name, self.dim = name, dim
        if dim == 2:
            self.mesh = dmesh.create_unit_square(MPI.COMM_SELF, 1, 1)
        else:
            self.mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
        self.u = fem.Function(fem.functionspace(self.mesh, ("Lagrange", 1, (dim,))))
        F = ufl.variable(ufl.Identity(dim) + ufl.grad(self.u))
        self.material = None
        correction = None
        if name == "stable_neo_hookean":
            psi = stable_neo_hookean(F, PARAMS)
            closed = stable_neo_hookean_stress(F, PARAMS)
            points = np.full((1, dim), 1.0 / (dim + 1))
        else:
            if name == "fixed_corotated":
                self.material = FixedCorotated(PARAMS, quadrature_degree=1)
            elif name == "arap":
                self.material = ARAP(PARAMS.mu, quadrature_degree=1)
            else:
                self.material = CorotationalLinear(PARAMS, quadrature_degree=1)
            psi = self.material(F)
            closed = self.material.stress(F)
            if hasattr(self.material, "tangent_correction"):
                correction = self.material.tangent_correction(F)
            points = self.material.field.rotation.points
        P = ufl.diff(psi, F)
        K = ufl.diff(P, F)
        Kc = ufl.diff(ufl.diff(correction, F), F) if correction is not None else ufl.zero((dim,) * 4)
        idx2 = [(i, j) for i in range(dim) for j in range(dim)]
        idx4 = [(i, j, p, q) for i, j in idx2 for p, q in idx2]
        entries = [psi] + [P[a] for a in idx2] + [closed[a] for a in idx2]
        entries += [K[a] for a in idx4] + [Kc[a] for a in idx4]
        self.expr = fem.Expression(ufl.as_vector(entries), points, jit_options=JIT_OPTIONS)
        self.cells = np.array([0], dtype=np.int32)

    def set(self, F: np.ndarray, refresh: bool = True) -> None:
        A = F - np.eye(self.dim)
        self.u.interpolate(lambda x: A @ x[: self.dim])
        if refresh and self.material is not None:
            if isinstance(self.material, CorotationalLinear):
                self.material.updater.update(0.0)
            else:
                self.material.refresh()

    def __call__(self, F: np.ndarray, refresh: bool = True):
        """(psi, P_ufl, P_closed, K) with K the full tangent (frozen part + correction)."""
        psi, P, Pc, Kf, Kc = self.parts(F, refresh)
        return psi, P, Pc, Kf + Kc

    def parts(self, F: np.ndarray, refresh: bool = True):
        self.set(F, refresh)
        d = self.dim
        v = self.expr.eval(self.mesh, self.cells).reshape(-1)
        n2, n4 = d * d, d**4
        out = [v[0], v[1 : 1 + n2].reshape(d, d), v[1 + n2 : 1 + 2 * n2].reshape(d, d)]
        out.append(v[1 + 2 * n2 : 1 + 2 * n2 + n4].reshape((d,) * 4))
        out.append(v[1 + 2 * n2 + n4 :].reshape((d,) * 4))
        return tuple(out)


@cache
def point(name: str, dim: int) -> _Point:
    return _Point(name, dim)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", MATERIALS)
def test_rest_state_and_linear_elasticity_at_identity(name, dim):
    """psi(I) = 0, P(I) = 0, and the tangent at I is the linear-elasticity tensor (ARAP: lambda = 0)."""
    psi, P, Pc, K = point(name, dim)(np.eye(dim))
    mu = PARAMS.mu
    assert abs(psi) < 1e-13 * mu
    assert np.abs(P).max() < 1e-13 * mu and np.abs(Pc).max() < 1e-13 * mu
    lam = 0.0 if name == "arap" else PARAMS.lmbda
    np.testing.assert_allclose(K, linear_tensor(mu, lam, dim), atol=1e-12 * (mu + lam))


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", MATERIALS)
def test_stress_matches_closed_form(name, dim):
    """UFL-derived P (rotation frozen at R(F)) = closed form = an independent NumPy formula."""
    ev = point(name, dim)
    rng = np.random.default_rng(10 + dim)
    for _ in range(3):
        F = random_F(rng, dim)
        psi, P, Pc, _ = ev(F)
        psi_np, P_np = closed_form_np(name, F)
        scale = np.abs(P_np).max()
        assert scale > 0.1 * PARAMS.mu
        assert psi == pytest.approx(psi_np, rel=1e-12)
        np.testing.assert_allclose(P, P_np, atol=1e-12 * scale)
        np.testing.assert_allclose(Pc, P_np, atol=1e-12 * scale)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", MATERIALS)
def test_stress_is_the_derivative_of_the_energy(name, dim):
    """Central differences of psi(F) — with R(F) recomputed at every F — equal P.

    For fixed-corotated and ARAP this is the closest-rotation argument: the
    derivative of ||F - R(F)||^2 is 2 (F - R). COR holds R^n fixed (a step quantity).
    """
    ev = point(name, dim)
    rng = np.random.default_rng(20 + dim)
    F = random_F(rng, dim, scale=0.25)
    refresh = name != "corotational"
    if not refresh:
        ev.set(random_F(rng, dim, scale=0.25))  # R^n from another state
        ev.material.updater.update(0.0)
    _, P, _, _ = ev(F, refresh=refresh)
    h = 1e-6
    fd = np.zeros((dim, dim))
    for i in range(dim):
        for j in range(dim):
            dF = np.zeros((dim, dim))
            dF[i, j] = h
            fd[i, j] = (ev(F + dF, refresh)[0] - ev(F - dF, refresh)[0]) / (2 * h)
    np.testing.assert_allclose(fd, P, atol=1e-7 * np.abs(P).max())


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", MATERIALS)
def test_tangent_is_the_derivative_of_the_stress(name, dim):
    """Central differences of P(F) equal the tangent; for FC/ARAP only with the dR/dF correction."""
    ev = point(name, dim)
    rng = np.random.default_rng(30 + dim)
    F = random_F(rng, dim, scale=0.25)
    refresh = name != "corotational"
    _, _, _, K_frozen, K_corr = ev.parts(F, refresh)
    h = 1e-6
    fd = np.zeros((dim,) * 4)
    for k in range(dim):
        for l in range(dim):  # noqa: E741
            dF = np.zeros((dim, dim))
            dF[k, l] = h
            fd[:, :, k, l] = (ev(F + dF, refresh)[1] - ev(F - dF, refresh)[1]) / (2 * h)
    K = K_frozen + K_corr
    scale = np.abs(K).max()
    np.testing.assert_allclose(fd, K, atol=1e-6 * scale)
    if name in ("fixed_corotated", "arap"):
        # Control: the frozen-R tangent misses -2 mu dR/dF, a first-order part of the tangent.
        assert np.abs(fd - K_frozen).max() > 0.05 * PARAMS.mu
        U, s, V = polar_svd(F[None])
        np.testing.assert_allclose(K_corr, -2 * PARAMS.mu * rotation_derivative(U, s, V)[0], atol=1e-12 * scale)
    else:
        assert np.abs(K_corr).max() == 0.0


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", ["stable_neo_hookean", "fixed_corotated", "arap"])
def test_objectivity(name, dim):
    """psi(QF) = psi(F) and P(QF) = Q P(F)."""
    ev = point(name, dim)
    rng = np.random.default_rng(40 + dim)
    for _ in range(3):
        F = random_F(rng, dim)
        Q = random_rotation(rng, dim)
        psi, P, _, _ = ev(F)
        psi_Q, P_Q, _, _ = ev(Q @ F)
        assert abs(psi) > 1e-2 * PARAMS.mu
        assert psi_Q == pytest.approx(psi, rel=1e-12)
        np.testing.assert_allclose(P_Q, Q @ P, atol=1e-12 * np.abs(P).max())


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", MATERIALS)
def test_inverted_element_has_finite_restoring_energy(name, dim):
    """det F < 0: finite energy and stress equal to the closed form; FC/ARAP energy is mu sum (sigma_i - 1)^2 + ..."""
    F = inverted_F(dim)
    assert np.linalg.det(F) < 0
    psi, P, Pc, _ = point(name, dim)(F)
    assert np.isfinite(psi) and np.all(np.isfinite(P))
    assert psi > 0.1 * PARAMS.mu  # an inverted element stores energy: it is pushed back
    np.testing.assert_allclose(P, Pc, atol=1e-12 * np.abs(Pc).max())
    psi_np, P_np = closed_form_np(name, F)
    assert psi == pytest.approx(psi_np, rel=1e-12)
    np.testing.assert_allclose(P, P_np, atol=1e-11 * np.abs(P_np).max())
    if name in ("fixed_corotated", "arap"):
        _, sigma, _ = polar_svd(F[None])
        assert sigma[0, -1] < 0  # the signed singular value of the sign fix
        lam = PARAMS.lmbda if name == "fixed_corotated" else 0.0
        expected = PARAMS.mu * np.sum((sigma[0] - 1.0) ** 2) + 0.5 * lam * (np.linalg.det(F) - 1.0) ** 2
        assert psi == pytest.approx(expected, rel=1e-12)


# --------------------------------------------------------------------------
# COR
# --------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [2, 3])
def test_corotational_is_linear_elasticity_for_small_strain(dim):
    """With R^n = I, COR is linear elasticity exactly; with R^n = R(F) it differs by O(|grad u|^2)."""
    ev = point("corotational", dim)
    rng = np.random.default_rng(50 + dim)
    G = rng.standard_normal((dim, dim))
    ev.set(np.eye(dim))
    ev.material.updater.update(0.0)
    F = np.eye(dim) + 0.05 * G
    psi, P, _, _ = ev(F, refresh=False)
    psi_lin, P_lin = closed_form_np("corotational", F, R=np.eye(dim))
    assert psi == pytest.approx(psi_lin, rel=1e-13)
    np.testing.assert_allclose(P, P_lin, atol=1e-13 * np.abs(P_lin).max())
    differences = []
    for eps in 0.02 / 2.0 ** np.arange(4):
        F = np.eye(dim) + eps * G
        _, P, _, _ = ev(F)  # R^n from F itself
        differences.append(np.abs(P - closed_form_np("corotational", F, R=np.eye(dim))[1]).max())
    rates = np.log2(np.array(differences[:-1]) / np.array(differences[1:]))
    assert np.all(rates > 1.9), rates


@pytest.mark.parametrize("dim", [2, 3])
def test_corotational_rotated_small_strain_state(dim):
    """F = Q (I + eps): with R^n = R(F) = Q, psi = psi_lin(eps) and P = Q sigma(eps); linear elasticity is not."""
    ev = point("corotational", dim)
    rng = np.random.default_rng(60 + dim)
    e = 0.02 * rng.standard_normal((dim, dim))
    e = 0.5 * (e + e.T)
    Q = random_rotation(rng, dim)
    F = Q @ (np.eye(dim) + e)
    psi, P, _, _ = ev(F)
    np.testing.assert_allclose(ev.material.field.rotation.values()[0], Q, atol=1e-13)
    psi_e, P_e = closed_form_np("corotational", np.eye(dim) + e, R=np.eye(dim))
    assert psi == pytest.approx(psi_e, rel=1e-12)
    np.testing.assert_allclose(P, Q @ P_e, atol=1e-12 * np.abs(P_e).max())
    psi_lin, _ = closed_form_np("corotational", F, R=np.eye(dim))
    assert psi_lin > 10 * psi  # small-strain elasticity alone stores energy in the rotation


def test_corotational_factory_and_binding(comm):
    psi, updater = corotational_linear(PARAMS)
    assert isinstance(psi, CorotationalLinear) and updater is psi.updater
    assert isinstance(updater, hf.problem.protocol.Updater)
    mesh = dmesh.create_unit_square(comm, 2, 2)
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    problem = hf.HyperelasticProblem(domain, psi, bcs=[hf.Clamp("left")], updaters=[updater])
    assert problem.invertible
    assert [u for u in problem._updaters if u is updater] == [updater]  # collected once
    assert psi.field.quadrature_degree == problem.quadrature_degree
    with pytest.raises(ParameterError, match="one material object per problem"):
        hf.HyperelasticProblem(domain, psi, bcs=[hf.Clamp("left")])


# --------------------------------------------------------------------------
# Stable Neo-Hookean parameters
# --------------------------------------------------------------------------
def test_stable_neo_hookean_parameters():
    c = StableNeoHookeanParameters.from_lame(PARAMS)
    assert c.mu == pytest.approx(4 * PARAMS.mu / 3, rel=1e-15)
    assert c.lmbda == pytest.approx(PARAMS.lmbda + 5 * PARAMS.mu / 6, rel=1e-15)
    assert c.alpha == pytest.approx(1 + 0.75 * c.mu / c.lmbda, rel=1e-15)
    # The Lame pair with the smallest bulk modulus still maps to lambda' > 0.
    soft = StableNeoHookeanParameters.from_lame(LameParameters(mu=1.0, lmbda=-0.66))
    assert soft.lmbda > 0
    for bad in ({"mu": 0.0, "lmbda": 1.0}, {"mu": 1.0, "lmbda": -1.0}, {"mu": float("nan"), "lmbda": 1.0}):
        with pytest.raises(ParameterError, match="StableNeoHookeanParameters"):
            StableNeoHookeanParameters(**bad)
    with pytest.raises(ParameterError, match="ARAP"):
        ARAP(-1.0)
    with pytest.raises(ParameterError, match="FixedCorotated"):
        FixedCorotated(3.0)


# --------------------------------------------------------------------------
# On a mesh: Taylor tests and a solve
# --------------------------------------------------------------------------
STEPS = 4e-3 / 2.0 ** np.arange(5)


def _box_problem(comm, material, degree=1, bcs=None, loads=()):
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([1.0, 0.4, 0.3])], [3, 2, 2])
    domain = hf.Domain.from_locators(
        mesh, {"left": lambda x: np.isclose(x[0], 0.0), "boundary": lambda x: np.full(x.shape[1], True)}
    )
    return hf.HyperelasticProblem(
        domain, material, bcs=[hf.Clamp("left")] if bcs is None else bcs, loads=loads, degree=degree
    )


def _state(x, coeffs):
    out = np.zeros((3, x.shape[1]))
    for i in range(3):
        a = coeffs[i]
        out[i] = a[0] * x[0] + a[1] * x[1] ** 2 + a[2] * np.sin(3 * x[0] + x[2]) + a[3] * x[0] * x[1] * x[2]
    return out


class _Assembler:
    """Energy, residual, tangent at u + h du with the material fields refreshed there (no BCs)."""

    def __init__(self, problem):
        self.problem = problem
        self.comm = problem.domain.comm
        self.energy = fem.form(problem.energy, jit_options=JIT_OPTIONS)
        self.residual = fem.form(problem.residual, jit_options=JIT_OPTIONS)
        self.jacobian = fem.form(problem.jacobian, jit_options=JIT_OPTIONS)
        rng = np.random.default_rng(17)
        cu = 0.25 * rng.standard_normal((3, 4))
        problem.u.interpolate(lambda x: _state(x, cu))
        self.u0 = problem.u.x.array.copy()
        self.du = fem.Function(problem.V)
        cd = rng.standard_normal((3, 4))
        self.du.interpolate(lambda x: _state(x, cd))

    def set(self, h):
        self.problem.u.x.array[:] = self.u0 + h * self.du.x.array
        self.problem.u.x.scatter_forward()
        for hook in self.problem.state_hooks:
            hook()

    def Pi(self, h):
        self.set(h)
        return self.comm.allreduce(fem.assemble_scalar(self.energy), op=MPI.SUM)

    def R(self, h):
        self.set(h)
        b = fpetsc.assemble_vector(self.residual)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    def K_du(self, h):
        self.set(h)
        A = fpetsc.assemble_matrix(self.jacobian)
        A.assemble()
        x, y = A.createVecs()
        x.array[:] = self.du.x.array[: x.getLocalSize()]
        A.mult(x, y)
        x.destroy()
        A.destroy()
        return y

    def dot_du(self, b):
        n = b.getLocalSize()
        return self.comm.allreduce(float(np.dot(b.array_r, self.du.x.array[:n])), op=MPI.SUM)

    def tangent_remainders(self, steps):
        R0, Kdu = self.R(0.0), self.K_du(0.0)
        errors = []
        for h in steps:
            Rh = self.R(h)
            Rh.axpy(-1.0, R0)
            Rh.axpy(-h, Kdu)
            errors.append(Rh.norm())
            Rh.destroy()
        scale = Kdu.norm()
        R0.destroy()
        Kdu.destroy()
        return np.array(errors), scale


def _rates(errors, steps):
    errors = np.asarray(errors)
    return np.log(errors[:-1] / errors[1:]) / np.log(steps[:-1] / steps[1:])


@pytest.mark.parametrize("degree", [1, 2])
def test_fixed_corotated_taylor(comm, degree):
    """Energy -> residual and residual -> tangent remainders are O(h^2) with the refreshed rotation."""
    problem = _box_problem(comm, FixedCorotated(PARAMS), degree=degree)
    assert len(problem.state_hooks) == 1 and problem.tangent_correction is not None
    asm = _Assembler(problem)
    Pi0 = asm.Pi(0.0)
    R0 = asm.R(0.0)
    dPi = asm.dot_du(R0)
    R0.destroy()
    assert abs(dPi) > 1e-2
    e0 = np.array([abs(asm.Pi(h) - Pi0 - h * dPi) for h in STEPS])
    assert e0[-1] < 1e-2 * abs(STEPS[-1] * dPi)
    assert _rates(e0, STEPS).min() > 1.9, _rates(e0, STEPS)
    e1, scale = asm.tangent_remainders(STEPS)
    assert e1[-1] < 1e-3 * STEPS[-1] * scale
    assert _rates(e1, STEPS).min() > 1.9, _rates(e1, STEPS)


def test_frozen_rotation_tangent_is_first_order(comm):
    """Control: without the dR/dF term (exact_tangent=False) the residual remainder is O(h)."""
    problem = _box_problem(comm, ARAP(PARAMS, exact_tangent=False))
    assert problem.tangent_correction is None
    steps = STEPS * 1e-2
    e1, scale = _Assembler(problem).tangent_remainders(steps)
    rates = _rates(e1, steps)
    assert np.all(np.abs(rates - 1.0) < 0.1), rates
    assert e1[-1] > 1e-3 * steps[-1] * scale


@pytest.mark.parametrize("exact", [True, False], ids=["exact", "frozen"])
def test_patch_test_solved_through_state_hooks(comm, exact):
    """A large rotation plus stretch prescribed on the whole boundary: the affine field is the solution.

    The solver runs the problem's state hooks (the polar refresh); the exact
    tangent converges in fewer Newton iterations than the frozen-R one. No
    predictor (its linear solve would reproduce the affine field at once) and
    no inversion guard: the interior starts at zero with the boundary rotated,
    so first-layer cells start inverted, which an invertible energy tolerates.
    """
    theta = 0.6
    c, s = math.cos(theta), math.sin(theta)
    Q = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    A = Q @ np.diag([1.15, 0.95, 1.05]) - np.eye(3)

    def affine(x):
        return A @ x

    material = FixedCorotated(PARAMS, exact_tangent=exact)
    problem = _box_problem(comm, material, bcs=[hf.PrescribedDisplacement("boundary", affine)])
    solver = hf.NewtonSolver(
        problem, {"snes_rtol": 1e-11, "snes_atol": 1e-12, "snes_max_it": 200}, predictor=False, min_jacobian=None
    )
    assert solver.state_hooks  # picked up from the problem
    problem.set_time(1.0)
    before = material.field.refreshes
    record = solver.solve()
    assert record.converged, record
    assert material.field.refreshes >= before + record.iterations  # at least once per Newton state
    ue = fem.Function(problem.V)
    ue.interpolate(affine)
    n = problem.V.dofmap.index_map.size_local * 3
    err = comm.allreduce(np.abs(problem.u.x.array[:n] - ue.x.array[:n]).max(initial=0.0), op=MPI.MAX)
    assert err < 1e-9
    _patch_iterations[exact] = record.iterations
    if len(_patch_iterations) == 2:
        assert _patch_iterations[True] < _patch_iterations[False], _patch_iterations


_patch_iterations: dict[bool, int] = {}


def test_fields_and_the_volume_rule(comm):
    """P1: the rotation is cellwise constant (DG0), any rule works; P2: fields sit on the volume rule,
    and a load that would raise it is refused with the degree to pass."""
    mesh = dmesh.create_unit_cube(comm, 2, 2, 2)
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    load = hf.BodyForce(lambda X: ufl.as_vector([X[0] ** 6, 0.0, 0.0]))
    material = FixedCorotated(PARAMS)
    problem = hf.HyperelasticProblem(domain, material, bcs=[hf.Clamp("left")], loads=[load])
    assert material.field.rotation.cellwise_constant and material.quadrature_rule_degree is None
    raised = {i.metadata()["quadrature_degree"] for i in problem.energy_internal.integrals()}
    assert raised != {problem.quadrature_degree}  # the load did raise the rule
    with pytest.raises(ParameterError, match="pass quadrature_degree="):
        hf.HyperelasticProblem(domain, FixedCorotated(PARAMS), bcs=[hf.Clamp("left")], loads=[load], degree=2)
    material = FixedCorotated(PARAMS)
    problem = hf.HyperelasticProblem(
        domain, material, bcs=[hf.Clamp("left")], loads=[load], degree=2, quadrature_degree=8
    )
    assert material.quadrature_rule_degree == 8 == problem.quadrature_degree
    assert not material.field.rotation.cellwise_constant
    with pytest.raises(ParameterError, match="quadrature degree 4"):
        FixedCorotated(PARAMS, quadrature_degree=4).bind(problem.F, 8)
