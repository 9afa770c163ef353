"""Verification of the strain-energy densities and their parameter sets.

Every UFL expression is evaluated numerically with :class:`dolfinx.fem.Expression`
on a one-cell mesh (``MPI.COMM_SELF``, so each rank checks independently) with
the deformation gradient a :class:`dolfinx.fem.Constant`. One compiled
expression per (material, dimension) returns

    [psi(F), psi(Q F), dpsi/dF (UFL, flattened), closed-form P (flattened)]

and is re-evaluated for many values of ``F`` and ``Q``.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.errors import ParameterError
from hyperfem.materials import (
    LameParameters,
    linear_elastic,
    linear_elastic_stress,
    log_taylor3,
    neo_hookean,
    neo_hookean_stress,
    robust_neo_hookean,
    robust_neo_hookean_stress,
    saint_venant_kirchhoff,
    saint_venant_kirchhoff_stress,
)

PARAMS = LameParameters(mu=3.7, lmbda=11.3)

MATERIALS = {
    "neo_hookean": (neo_hookean, neo_hookean_stress),
    "robust_neo_hookean": (robust_neo_hookean, robust_neo_hookean_stress),
    "saint_venant_kirchhoff": (saint_venant_kirchhoff, saint_venant_kirchhoff_stress),
    "linear_elastic": (linear_elastic, linear_elastic_stress),
}
OBJECTIVE = ["neo_hookean", "robust_neo_hookean", "saint_venant_kirchhoff"]


# Each rank compiles on MPI.COMM_SELF into the shared cache; a rank that finds the
# module being compiled by another waits for it (10 s by default: too short on a busy machine).
JIT_OPTIONS = {"timeout": 300}

class _Evaluator:
    """psi, psi(QF), UFL dpsi/dF and closed-form P of one material, as numbers."""

    def __init__(self, name: str, dim: int):
        psi_fn, stress_fn = MATERIALS[name]
        if dim == 2:
            self.mesh = dmesh.create_unit_square(MPI.COMM_SELF, 1, 1)
        else:
            self.mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
        self.dim = dim
        self.Fc = fem.Constant(self.mesh, np.eye(dim))
        self.Qc = fem.Constant(self.mesh, np.eye(dim))
        F = ufl.variable(self.Fc)
        psi = psi_fn(F, PARAMS)
        P_ufl = ufl.diff(psi, F)
        P_closed = stress_fn(self.Fc, PARAMS)
        psi_QF = psi_fn(self.Qc * self.Fc, PARAMS)
        idx = [(i, j) for i in range(dim) for j in range(dim)]
        entries = [psi, psi_QF] + [P_ufl[i, j] for i, j in idx] + [P_closed[i, j] for i, j in idx]
        self.expr = fem.Expression(
            ufl.as_vector(entries), np.full((1, dim), 1.0 / (dim + 2)), jit_options=JIT_OPTIONS
        )
        self.cells = np.array([0], dtype=np.int32)

    def __call__(self, F: np.ndarray, Q: np.ndarray | None = None):
        d = self.dim
        self.Fc.value[:] = F
        self.Qc.value[:] = np.eye(d) if Q is None else Q
        v = self.expr.eval(self.mesh, self.cells).reshape(-1)
        n = d * d
        return v[0], v[1], v[2 : 2 + n].reshape(d, d), v[2 + n :].reshape(d, d)


@cache
def evaluator(name: str, dim: int) -> _Evaluator:
    return _Evaluator(name, dim)


def random_F(rng: np.random.Generator, dim: int, scale: float = 0.3) -> np.ndarray:
    """A random non-trivial deformation gradient with det F > 0.2."""
    while True:
        F = np.eye(dim) + scale * rng.standard_normal((dim, dim))
        if np.linalg.det(F) > 0.2:
            return F


def random_rotation(rng: np.random.Generator, dim: int) -> np.ndarray:
    """A random proper rotation (det = +1), far from the identity."""
    while True:
        Q, R = np.linalg.qr(rng.standard_normal((dim, dim)))
        Q = Q @ np.diag(np.sign(np.diag(R)))
        if np.linalg.det(Q) < 0:
            Q[:, 0] *= -1
        if np.linalg.norm(Q - np.eye(dim)) > 0.5:
            return Q


def rotation_z(theta: float, dim: int) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    Q = np.eye(dim)
    Q[:2, :2] = [[c, -s], [s, c]]
    return Q


# --------------------------------------------------------------------------
# Reference configuration
# --------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_stress_free_reference(name, dim):
    psi, _, P_ufl, P_closed = evaluator(name, dim)(np.eye(dim))
    assert abs(psi) < 1e-14 * PARAMS.mu
    assert np.max(np.abs(P_ufl)) < 1e-13 * PARAMS.mu
    assert np.max(np.abs(P_closed)) < 1e-13 * PARAMS.mu


# --------------------------------------------------------------------------
# UFL derivative against the closed-form stress
# --------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_ufl_stress_matches_closed_form(name, dim):
    ev = evaluator(name, dim)
    rng = np.random.default_rng(1234 + dim)
    for _ in range(5):
        F = random_F(rng, dim)
        psi, _, P_ufl, P_closed = ev(F)
        assert np.isfinite(psi)
        scale = np.max(np.abs(P_closed))
        assert scale > 0.1 * PARAMS.mu  # a genuinely stressed state
        np.testing.assert_allclose(P_ufl, P_closed, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", list(MATERIALS))
def test_closed_form_stress_is_derivative_of_energy(name, dim):
    """Independent of UFL's differentiation: central differences of psi."""
    ev = evaluator(name, dim)
    rng = np.random.default_rng(99 + dim)
    F = random_F(rng, dim, scale=0.2)
    _, _, _, P = ev(F)
    h = 1e-5
    fd = np.zeros((dim, dim))
    for i in range(dim):
        for j in range(dim):
            dF = np.zeros((dim, dim))
            dF[i, j] = h
            fd[i, j] = (ev(F + dF)[0] - ev(F - dF)[0]) / (2 * h)
    np.testing.assert_allclose(fd, P, rtol=0, atol=1e-7 * np.max(np.abs(P)))


@pytest.mark.parametrize("dim", [2, 3])
def test_neo_hookean_closed_form_numbers(dim):
    """psi and P of the Neo-Hookean law against numpy (seed 000, eq. 2.8)."""
    rng = np.random.default_rng(7)
    F = random_F(rng, dim)
    psi, _, P_ufl, _ = evaluator("neo_hookean", dim)(F)
    mu, lam = PARAMS.mu, PARAMS.lmbda
    J = np.linalg.det(F)
    psi_np = 0.5 * mu * (np.sum(F * F) - dim) - mu * np.log(J) + 0.5 * lam * np.log(J) ** 2
    P_np = mu * F + (lam * np.log(J) - mu) * np.linalg.inv(F).T
    assert psi == pytest.approx(psi_np, rel=1e-13)
    np.testing.assert_allclose(P_ufl, P_np, rtol=0, atol=1e-12 * np.max(np.abs(P_np)))


@pytest.mark.parametrize("dim", [2, 3])
def test_saint_venant_kirchhoff_closed_form_numbers(dim):
    rng = np.random.default_rng(8)
    F = random_F(rng, dim)
    psi, _, P_ufl, _ = evaluator("saint_venant_kirchhoff", dim)(F)
    mu, lam = PARAMS.mu, PARAMS.lmbda
    E = 0.5 * (F.T @ F - np.eye(dim))
    psi_np = mu * np.sum(E * E) + 0.5 * lam * np.trace(E) ** 2
    P_np = F @ (2 * mu * E + lam * np.trace(E) * np.eye(dim))
    assert psi == pytest.approx(psi_np, rel=1e-13)
    np.testing.assert_allclose(P_ufl, P_np, rtol=0, atol=1e-12 * np.max(np.abs(P_np)))


@pytest.mark.parametrize("dim", [2, 3])
def test_linear_elastic_closed_form_numbers(dim):
    rng = np.random.default_rng(9)
    F = random_F(rng, dim, scale=0.05)
    psi, _, P_ufl, _ = evaluator("linear_elastic", dim)(F)
    mu, lam = PARAMS.mu, PARAMS.lmbda
    eps = 0.5 * (F + F.T) - np.eye(dim)
    psi_np = mu * np.sum(eps * eps) + 0.5 * lam * np.trace(eps) ** 2
    P_np = 2 * mu * eps + lam * np.trace(eps) * np.eye(dim)
    assert psi == pytest.approx(psi_np, rel=1e-12)
    np.testing.assert_allclose(P_ufl, P_np, rtol=0, atol=1e-12 * np.max(np.abs(P_np)))


# --------------------------------------------------------------------------
# Objectivity
# --------------------------------------------------------------------------
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", OBJECTIVE)
def test_objectivity(name, dim):
    ev = evaluator(name, dim)
    rng = np.random.default_rng(4321 + dim)
    for _ in range(5):
        F = random_F(rng, dim)
        Q = random_rotation(rng, dim)
        psi, psi_QF, P, _ = ev(F, Q)
        assert abs(psi) > 1e-2 * PARAMS.mu
        assert psi_QF == pytest.approx(psi, rel=1e-12)
        # The stress rotates with Q: P(QF) = Q P(F).
        _, _, P_QF, _ = ev(Q @ F)
        np.testing.assert_allclose(P_QF, Q @ P, rtol=0, atol=1e-12 * np.max(np.abs(P)))


@pytest.mark.parametrize("dim", [2, 3])
def test_linear_elastic_not_objective(dim):
    """A finite rigid rotation stores energy in small-strain elasticity."""
    ev = evaluator("linear_elastic", dim)
    theta = math.pi / 6
    Q = rotation_z(theta, dim)
    psi_I, psi_Q, _, _ = ev(np.eye(dim), Q)
    assert psi_I == pytest.approx(0.0, abs=1e-14)
    # eps(Q) = (cos(theta) - 1) in the rotation plane.
    expected = 2.0 * (math.cos(theta) - 1.0) ** 2 * (PARAMS.mu + PARAMS.lmbda)
    assert psi_Q == pytest.approx(expected, rel=1e-12)
    assert psi_Q > 1e-2 * PARAMS.mu
    # Also for a stressed state and a random rotation.
    rng = np.random.default_rng(5)
    F = random_F(rng, dim, scale=0.1)
    psi, psi_QF, _, _ = ev(F, random_rotation(rng, dim))
    assert abs(psi_QF - psi) > 1e-2 * abs(psi)


# --------------------------------------------------------------------------
# Inversion-robust Neo-Hookean (seed 000, eq. 2.9 / 2.19)
# --------------------------------------------------------------------------
def test_log_taylor3_coefficients():
    """r(x) = (x-1) - (x-1)^2/2 + (x-1)^3/3 = -11/6 + 3x - 3x^2/2 + x^3/3 (eq. 2.9a)."""
    x = np.linspace(-2.0, 3.0, 11)
    np.testing.assert_allclose(log_taylor3(x), -11 / 6 + 3 * x - 1.5 * x**2 + x**3 / 3, rtol=0, atol=1e-13)
    assert log_taylor3(1.0) == 0.0


def test_log_taylor3_fourth_order_agreement():
    """r(J) - ln J = (J-1)^4/4 + O((J-1)^5): third-order accurate at J = 1."""
    for sign in (1.0, -1.0):
        deltas = sign * 0.08 / 2.0 ** np.arange(5)
        err = log_taylor3(1.0 + deltas) - np.log1p(deltas)
        # r - ln(1 + d) = d^4/4 - d^5/5 + O(d^6)
        ratio = err / deltas**4
        np.testing.assert_allclose(ratio - (0.25 - deltas / 5), 0.0, rtol=0, atol=np.max(deltas**2))
        rates = np.log2(np.abs(err[:-1] / err[1:]))
        assert np.all(np.abs(rates - 4.0) < 0.1), rates


def test_log_taylor3_finite_for_nonpositive_J():
    J = np.array([0.0, -0.5, -1.0, -3.0])
    r = log_taylor3(J)
    assert np.all(np.isfinite(r))
    np.testing.assert_allclose(r, (J - 1) - (J - 1) ** 2 / 2 + (J - 1) ** 3 / 3, rtol=1e-15)
    assert r[0] == pytest.approx(-11 / 6)


@pytest.mark.parametrize("dim", [2, 3])
def test_robust_neo_hookean_inverted_element(dim):
    """An inverted F has finite energy and stress; the classic law gives NaN."""
    F = np.eye(dim)
    F[0, 0] = -0.7
    F[1, 0] = 0.2
    J = np.linalg.det(F)
    assert J < 0
    psi, _, P_ufl, P_closed = evaluator("robust_neo_hookean", dim)(F)
    mu, lam = PARAMS.mu, PARAMS.lmbda
    r = log_taylor3(J)
    psi_np = 0.5 * mu * (np.sum(F * F) - dim) - mu * r + 0.5 * lam * r**2
    assert np.isfinite(psi) and psi == pytest.approx(psi_np, rel=1e-13)
    assert np.all(np.isfinite(P_ufl))
    np.testing.assert_allclose(P_ufl, P_closed, rtol=0, atol=1e-12 * np.max(np.abs(P_closed)))
    # J = 0 (degenerate) still has finite energy.
    F0 = np.eye(dim)
    F0[0, 0] = 0.0
    assert np.isfinite(evaluator("robust_neo_hookean", dim)(F0)[0])
    # The logarithmic law cannot evaluate an inverted element.
    assert not np.isfinite(evaluator("neo_hookean", dim)(F)[0])


@pytest.mark.parametrize("dim", [2, 3])
def test_robust_matches_neo_hookean_near_identity(dim):
    """psi_robust - psi_NH = O((J-1)^4) for small deformations."""
    rng = np.random.default_rng(11)
    G = rng.standard_normal((dim, dim))
    diffs, dets = [], []
    for eps in 0.04 / 2.0 ** np.arange(4):
        F = np.eye(dim) + eps * G
        diffs.append(evaluator("robust_neo_hookean", dim)(F)[0] - evaluator("neo_hookean", dim)(F)[0])
        dets.append(np.linalg.det(F) - 1.0)
    diffs, dets = np.abs(diffs), np.abs(dets)
    rates = np.log(diffs[:-1] / diffs[1:]) / np.log(dets[:-1] / dets[1:])
    assert np.all(rates > 3.8), rates


# --------------------------------------------------------------------------
# LameParameters
# --------------------------------------------------------------------------
@pytest.mark.parametrize("E,nu", [(1e6, 0.3), (1000.0, 0.45), (2.5e9, 0.0), (7.0, -0.4), (1.0, 0.4999)])
def test_from_youngs(E, nu):
    p = LameParameters.from_youngs(E, nu)
    assert p.mu == pytest.approx(E / (2 * (1 + nu)), rel=1e-15)
    assert p.lmbda == pytest.approx(E * nu / ((1 + nu) * (1 - 2 * nu)), rel=1e-15, abs=1e-300)
    assert p.youngs_modulus == pytest.approx(E, rel=1e-11)
    assert p.poisson_ratio == pytest.approx(nu, rel=1e-11, abs=1e-15)
    assert p.bulk_modulus == pytest.approx(E / (3 * (1 - 2 * nu)), rel=1e-11)


def test_from_youngs_known_values():
    p = LameParameters.from_youngs(E=1e6, nu=0.3)
    assert p.mu == pytest.approx(384615.38461538462, rel=1e-14)
    assert p.lmbda == pytest.approx(576923.07692307692, rel=1e-14)


def test_lame_round_trip():
    p = LameParameters(mu=2.0, lmbda=5.0)
    q = LameParameters.from_youngs(p.youngs_modulus, p.poisson_ratio)
    assert q.mu == pytest.approx(p.mu, rel=1e-14)
    assert q.lmbda == pytest.approx(p.lmbda, rel=1e-14)


@pytest.mark.parametrize("E", [0.0, -1.0, float("nan"), float("inf")])
def test_from_youngs_rejects_bad_E(E):
    with pytest.raises(ParameterError, match=r"\bE\b"):
        LameParameters.from_youngs(E, 0.3)


@pytest.mark.parametrize("nu", [0.5, 0.7, -1.0, -2.0, float("nan")])
def test_from_youngs_rejects_bad_nu(nu):
    with pytest.raises(ParameterError, match=r"\bnu\b"):
        LameParameters.from_youngs(1e6, nu)


@pytest.mark.parametrize(
    "mu,lmbda,name",
    [
        (0.0, 1.0, "mu"),
        (-1.0, 1.0, "mu"),
        (float("nan"), 1.0, "mu"),
        (1.0, float("nan"), "lmbda"),
        (1.0, -1.0, "bulk modulus"),
    ],
)
def test_lame_parameters_reject_bad_values(mu, lmbda, name):
    with pytest.raises(ParameterError, match=name):
        LameParameters(mu=mu, lmbda=lmbda)


def test_parameter_error_is_value_error():
    assert issubclass(ParameterError, ValueError)
    assert issubclass(ParameterError, hf.HyperfemError)
