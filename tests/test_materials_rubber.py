r"""Verification of the isotropic rubber laws: Yeoh, reduced polynomial, Gent, Arruda–Boyce, Veronda–Westmann.

Every law is an isochoric function :math:`\psi(\bar I_1, \bar I_2)` plus the
volumetric :math:`U(J) = \tfrac K2 (\ln J)^2`. Each is compiled once into a
:class:`dolfinx.fem.Expression` on a one-cell mesh (``MPI.COMM_SELF``, so every
rank checks independently) with the deformation gradient a
:class:`dolfinx.fem.Constant`, returning :math:`\psi(F)`, :math:`\psi(QF)`,
:math:`\psi` of a 2×2 (plane-strain) gradient, UFL's :math:`\partial\psi/\partial F`,
the module's closed-form :math:`P` and UFL's tangent :math:`\partial^2\psi/\partial F^2`.

Independent references are written here in NumPy from the published formulas:
the energy, :math:`\psi_1 = \partial\psi/\partial\bar I_1`,
:math:`\psi_2 = \partial\psi/\partial\bar I_2`, and the incompressible uniaxial
nominal stress :math:`N = 2(\lambda - \lambda^{-2})(\psi_1 + \psi_2/\lambda)` at
:math:`F = \operatorname{diag}(\lambda, \lambda^{-1/2}, \lambda^{-1/2})`, where the
UFL stress with the hydrostatic pressure eliminated by the traction-free lateral
faces is :math:`P_{11} - \lambda^{-3/2} P_{22}` (:math:`U'(1) = 0`).

Taylor tests (energy → residual → tangent) run on a small box on ``MPI.COMM_WORLD``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem
from dolfinx import mesh as dmesh

from hyperfem.errors import ParameterError
from taylor_checks import taylor_rates
from hyperfem.materials.arruda_boyce import (
    ARRUDA_BOYCE_COEFFICIENTS,
    ArrudaBoyceParameters,
    arruda_boyce,
    arruda_boyce_isochoric,
    arruda_boyce_stress,
)
from hyperfem.materials.gent import GentParameters, gent, gent_isochoric, gent_stress
from hyperfem.materials.veronda_westmann import (
    VerondaWestmannParameters,
    veronda_westmann,
    veronda_westmann_isochoric,
    veronda_westmann_stress,
)
from hyperfem.materials.yeoh import (
    ReducedPolynomialParameters,
    YeohParameters,
    reduced_polynomial,
    reduced_polynomial_isochoric,
    reduced_polynomial_stress,
    yeoh,
    yeoh_isochoric,
    yeoh_stress,
)

JIT_OPTIONS = {"timeout": 300}
K = 20.0


@dataclass(frozen=True)
class Law:
    """A law under test with its NumPy references (functions of the isochoric invariants)."""

    psi: Callable[[Any, Any], Any]
    iso: Callable[[Any, Any], Any]  # the isochoric part (mixed formulation)
    stress: Callable[[Any, Any], Any]
    params: Any
    W: Callable[[float, float], float]  # isochoric energy of (I1bar, I2bar)
    dW: Callable[[float, float], tuple[float, float]]  # (psi_1, psi_2)
    mu0: float  # documented small-strain shear modulus


def _poly(coeffs):
    def W(I1, _I2):
        return sum(c * (I1 - 3.0) ** (i + 1) for i, c in enumerate(coeffs))

    def dW(I1, _I2):
        return sum((i + 1) * c * (I1 - 3.0) ** i for i, c in enumerate(coeffs)), 0.0

    return W, dW


def _gent(mu, Jm, f=None):
    def W(I1, _I2):
        x = (I1 - 3.0) / Jm
        if f is None or x < f:
            return -0.5 * mu * Jm * math.log(1.0 - x)
        s = x - f
        return 0.5 * mu * Jm * (-math.log(1.0 - f) + s / (1.0 - f) + 0.5 * s * s / (1.0 - f) ** 2)

    def dW(I1, _I2):
        x = (I1 - 3.0) / Jm
        if f is None or x < f:
            return 0.5 * mu / (1.0 - x), 0.0
        return 0.5 * mu * (1.0 / (1.0 - f) + (x - f) / (1.0 - f) ** 2), 0.0

    return W, dW


def _arruda_boyce(mu, lm):
    C = ARRUDA_BOYCE_COEFFICIENTS

    def W(I1, _I2):
        return mu * sum(C[i] / lm ** (2 * i) * (I1 ** (i + 1) - 3.0 ** (i + 1)) for i in range(5))

    def dW(I1, _I2):
        return mu * sum((i + 1) * C[i] / lm ** (2 * i) * I1**i for i in range(5)), 0.0

    return W, dW


def _veronda_westmann(c1, c2):
    def W(I1, I2):
        return c1 * (math.exp(c2 * (I1 - 3.0)) - 1.0) - 0.5 * c1 * c2 * (I2 - 3.0)

    def dW(I1, _I2):
        return c1 * c2 * math.exp(c2 * (I1 - 3.0)), -0.5 * c1 * c2

    return W, dW


YEOH = YeohParameters(c10=0.5, c20=-0.04, c30=0.006, K=K)
POLY = ReducedPolynomialParameters((0.4, 0.03, -0.002, 0.0004), K=K)
GENT = GentParameters(mu=1.1, Jm=10.0, K=K)
GENT_EXT = GentParameters(mu=1.1, Jm=10.0, K=K, lock_fraction=0.5)  # lambda = 3 uniaxial: x = 0.67 > 0.5
AB = ArrudaBoyceParameters(mu=0.9, lambda_m=2.5, K=K)
VW = VerondaWestmannParameters(c1=0.3, c2=0.8, K=K)

LAWS = {
    "yeoh": Law(yeoh, yeoh_isochoric, yeoh_stress, YEOH, *_poly(YEOH.coefficients), mu0=2 * 0.5),
    "reduced_polynomial": Law(
        reduced_polynomial,
        reduced_polynomial_isochoric,
        reduced_polynomial_stress,
        POLY,
        *_poly(POLY.coefficients),
        mu0=2 * 0.4,
    ),
    "gent": Law(gent, gent_isochoric, gent_stress, GENT, *_gent(1.1, 10.0), mu0=1.1),
    "gent_extended": Law(gent, gent_isochoric, gent_stress, GENT_EXT, *_gent(1.1, 10.0, 0.5), mu0=1.1),
    "arruda_boyce": Law(
        arruda_boyce,
        arruda_boyce_isochoric,
        arruda_boyce_stress,
        AB,
        *_arruda_boyce(0.9, 2.5),
        mu0=0.9 * (1 + 3 / (5 * 2.5**2) + 99 / (175 * 2.5**4) + 513 / (875 * 2.5**6) + 42039 / (67375 * 2.5**8)),
    ),
    "veronda_westmann": Law(
        veronda_westmann,
        veronda_westmann_isochoric,
        veronda_westmann_stress,
        VW,
        *_veronda_westmann(0.3, 0.8),
        mu0=0.24,
    ),
}


# --------------------------------------------------------------------------
# Point evaluation of constant-F expressions
# --------------------------------------------------------------------------
class _Evaluator:
    """psi(F), psi(QF), psi(F2) (2x2), UFL P, closed-form P, UFL tangent of one law, as numbers."""

    def __init__(self, name: str):
        law = LAWS[name]
        self.mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
        self.Fc = fem.Constant(self.mesh, np.eye(3))
        self.Qc = fem.Constant(self.mesh, np.eye(3))
        self.F2c = fem.Constant(self.mesh, np.eye(2))
        F = ufl.variable(self.Fc)
        psi = law.psi(F, law.params)
        P = ufl.diff(psi, F)
        A = ufl.diff(P, F)
        scalars = [psi, law.psi(self.Qc * self.Fc, law.params), law.psi(self.F2c, law.params), law.iso(F, law.params)]
        P_closed = law.stress(self.Fc, law.params)
        entries = scalars + [P[i] for i in np.ndindex(3, 3)] + [P_closed[i] for i in np.ndindex(3, 3)]
        entries += [A[i] for i in np.ndindex(3, 3, 3, 3)]
        self.expr = fem.Expression(ufl.as_vector(entries), np.array([[0.25, 0.25, 0.25]]), jit_options=JIT_OPTIONS)
        self.cells = np.array([0], dtype=np.int32)

    def __call__(self, F: np.ndarray, Q: np.ndarray | None = None, F2: np.ndarray | None = None) -> dict:
        self.Fc.value[:] = F
        self.Qc.value[:] = np.eye(3) if Q is None else Q
        self.F2c.value[:] = np.eye(2) if F2 is None else F2
        v = self.expr.eval(self.mesh, self.cells).reshape(-1)
        return {
            "psi": v[0],
            "psi_QF": v[1],
            "psi_2d": v[2],
            "psi_iso": v[3],
            "P": v[4:13].reshape(3, 3),
            "P_closed": v[13:22].reshape(3, 3),
            "A": v[22:].reshape(3, 3, 3, 3),
        }


@cache
def evaluator(name: str) -> _Evaluator:
    return _Evaluator(name)


def random_F(rng: np.random.Generator, scale: float = 0.3) -> np.ndarray:
    while True:
        F = np.eye(3) + scale * rng.standard_normal((3, 3))
        if np.linalg.det(F) > 0.2:
            return F


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    while True:
        Q, R = np.linalg.qr(rng.standard_normal((3, 3)))
        Q = Q @ np.diag(np.sign(np.diag(R)))
        if np.linalg.det(Q) < 0:
            Q[:, 0] *= -1
        if np.linalg.norm(Q - np.eye(3)) > 0.5:
            return Q


def test_states() -> list[np.ndarray]:
    """Random gradients plus large ones: uniaxial to lambda = 3 (rotated), simple shear 1.5, compression 0.5."""
    rng = np.random.default_rng(2024)
    states = [random_F(rng) for _ in range(4)]
    R1, R2 = random_rotation(rng), random_rotation(rng)
    states.append(R1 @ np.diag([3.0, 3.0**-0.5, 3.0**-0.5]) @ R2 * 1.05)
    shear = np.eye(3)
    shear[0, 1] = 1.5
    states.append(shear @ np.diag([1.0, 0.97, 1.02]))
    states.append(R2 @ np.diag([0.5, 1.3, 1.4]))
    return states


test_states.__test__ = False  # a helper, not a test


def isochoric_invariants_np(F: np.ndarray) -> tuple[float, float, float]:
    C = F.T @ F
    J = np.linalg.det(F)
    I1 = np.trace(C)
    I2 = 0.5 * (I1**2 - np.trace(C @ C))
    return J ** (-2 / 3) * I1, J ** (-4 / 3) * I2, J


# --------------------------------------------------------------------------
# Reference state, tangent, energy values
# --------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(LAWS))
def test_stress_free_reference(name):
    v = evaluator(name)(np.eye(3))
    mu0 = LAWS[name].mu0
    assert abs(v["psi"]) < 1e-14 * mu0
    assert np.max(np.abs(v["P"])) < 1e-13 * mu0
    assert np.max(np.abs(v["P_closed"])) < 1e-13 * mu0


@pytest.mark.parametrize("name", list(LAWS))
def test_tangent_at_identity_and_shear_modulus(name):
    """At F = I the tangent is finite and isotropic: A_0101 = A_0110 = mu0 (documented), A_0000 = K + 4 mu0/3."""
    law = LAWS[name]
    A = evaluator(name)(np.eye(3))["A"]
    assert np.all(np.isfinite(A))
    assert law.params.shear_modulus == pytest.approx(law.mu0, rel=1e-14)
    assert A[0, 1, 0, 1] == pytest.approx(law.mu0, rel=1e-12)
    assert A[0, 1, 1, 0] == pytest.approx(law.mu0, rel=1e-12)
    assert A[0, 0, 0, 0] == pytest.approx(K + 4.0 * law.mu0 / 3.0, rel=1e-12)
    assert A[0, 0, 1, 1] == pytest.approx(K - 2.0 * law.mu0 / 3.0, rel=1e-12)


@pytest.mark.parametrize("name", list(LAWS))
def test_energy_matches_numpy(name):
    law = LAWS[name]
    ev = evaluator(name)
    for F in test_states():
        I1, I2, J = isochoric_invariants_np(F)
        v = ev(F)
        assert v["psi"] == pytest.approx(law.W(I1, I2) + 0.5 * K * math.log(J) ** 2, rel=1e-12)
        assert v["psi_iso"] == pytest.approx(law.W(I1, I2), rel=1e-12)  # the mixed formulation's part


# --------------------------------------------------------------------------
# Stress: UFL against closed form; uniaxial closed form
# --------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(LAWS))
def test_ufl_stress_matches_closed_form(name):
    ev = evaluator(name)
    worst = 0.0
    for F in test_states():
        v = ev(F)
        scale = np.max(np.abs(v["P_closed"]))
        assert np.all(np.isfinite(v["P"])) and scale > 0.05 * LAWS[name].mu0
        worst = max(worst, np.max(np.abs(v["P"] - v["P_closed"])) / scale)
    assert worst < 1e-12, worst


@pytest.mark.parametrize("name", list(LAWS))
def test_incompressible_uniaxial_nominal_stress(name):
    """N = 2 (lam - lam^-2)(psi_1 + psi_2 / lam) against P11 - lam^(-3/2) P22 at F = diag(lam, lam^-1/2, lam^-1/2)."""
    law = LAWS[name]
    ev = evaluator(name)
    for lam in (0.5, 0.8, 1.3, 2.0, 3.0):
        F = np.diag([lam, lam**-0.5, lam**-0.5])
        P = ev(F)["P"]
        assert P[1, 1] == pytest.approx(P[2, 2], rel=1e-13)
        assert np.max(np.abs(P - np.diag(np.diag(P)))) < 1e-13 * np.max(np.abs(P))
        I1, I2 = lam**2 + 2.0 / lam, 2.0 * lam + lam**-2
        psi1, psi2 = law.dW(I1, I2)
        N = 2.0 * (lam - lam**-2) * (psi1 + psi2 / lam)
        assert P[0, 0] - lam**-1.5 * P[1, 1] == pytest.approx(N, rel=1e-11)


# --------------------------------------------------------------------------
# Objectivity, plane strain
# --------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(LAWS))
def test_objectivity(name):
    ev = evaluator(name)
    rng = np.random.default_rng(5)
    for F in test_states():
        v = ev(F, Q=random_rotation(rng))
        assert v["psi_QF"] == pytest.approx(v["psi"], rel=1e-12)


@pytest.mark.parametrize("name", list(LAWS))
def test_plane_strain_is_the_embedded_3d_law(name):
    ev = evaluator(name)
    F2 = np.array([[1.4, 0.3], [-0.2, 0.8]])
    F3 = np.eye(3)
    F3[:2, :2] = F2
    assert ev(F3, F2=F2)["psi_2d"] == pytest.approx(ev(F3)["psi"], rel=1e-13)


# --------------------------------------------------------------------------
# Gent: the lock
# --------------------------------------------------------------------------
def _uniaxial_with_I1(I1bar: float) -> np.ndarray:
    """diag(lam, lam^-1/2, lam^-1/2) with lam^2 + 2/lam = I1bar (lam > 1)."""
    lo, hi = 1.0, math.sqrt(I1bar)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mid**2 + 2 / mid < I1bar else (lo, mid)
    lam = 0.5 * (lo + hi)
    return np.diag([lam, lam**-0.5, lam**-0.5])


def test_gent_exact_law_is_nan_beyond_the_lock():
    v = evaluator("gent")(_uniaxial_with_I1(3.0 + 1.2 * GENT.Jm))
    assert np.isnan(v["psi"]) and np.all(np.isnan(v["P"][np.diag_indices(3)])) and np.isnan(v["A"][0, 0, 0, 0])
    below = evaluator("gent")(_uniaxial_with_I1(3.0 + 0.99 * GENT.Jm))
    assert np.isfinite(below["psi"]) and np.all(np.isfinite(below["A"]))


def test_gent_extension_is_finite_and_smooth_across_the_onset():
    ext, exact = evaluator("gent_extended"), evaluator("gent")
    f, Jm = GENT_EXT.lock_fraction, GENT_EXT.Jm
    below = _uniaxial_with_I1(3.0 + 0.9 * f * Jm)
    assert ext(below)["psi"] == pytest.approx(exact(below)["psi"], rel=1e-14)
    np.testing.assert_allclose(ext(below)["P"], exact(below)["P"], rtol=1e-14, atol=0)
    beyond = ext(_uniaxial_with_I1(3.0 + 1.5 * Jm))  # far past the lock of the exact law
    assert np.isfinite(beyond["psi"]) and np.all(np.isfinite(beyond["P"])) and np.all(np.isfinite(beyond["A"]))
    # C^2 at the onset: energy, stress and tangent continuous across x = f
    d = 1e-7
    left, right = ext(_uniaxial_with_I1(3.0 + (f - d) * Jm)), ext(_uniaxial_with_I1(3.0 + (f + d) * Jm))
    for key, tol in (("psi", 1e-6), ("P", 1e-6), ("A", 1e-5)):
        jump = np.max(np.abs(np.asarray(right[key]) - np.asarray(left[key])))
        assert jump < tol * np.max(np.abs(left[key])), (key, jump)


def test_arruda_boyce_from_initial_shear_modulus():
    p = ArrudaBoyceParameters.from_initial_shear_modulus(2.0, lambda_m=3.0, K=K)
    assert p.initial_shear_modulus == pytest.approx(2.0, rel=1e-15)
    assert p.mu < 2.0


# --------------------------------------------------------------------------
# Parameter validation
# --------------------------------------------------------------------------
@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: YeohParameters(c10=0.0, c20=0.0, c30=0.0, K=1.0), "YeohParameters: c10 must be"),
        (lambda: YeohParameters(c10=1.0, c20=float("nan"), c30=0.0, K=1.0), "YeohParameters: c20 must be"),
        (lambda: YeohParameters(c10=1.0, c20=0.0, c30=0.0, K=-1.0), "YeohParameters: K must be"),
        (lambda: YeohParameters(c10=1.0, c20=0.0, c30=0.0, K=1.0, volumetric="bad"), "unknown volumetric law"),
        (lambda: ReducedPolynomialParameters((), K=1.0), "ReducedPolynomialParameters: coefficients must hold"),
        (lambda: ReducedPolynomialParameters((-1.0, 2.0), K=1.0), r"coefficients\[0\] \(C10\) must be"),
        (lambda: ReducedPolynomialParameters((1.0, "x"), K=1.0), r"coefficients\[1\] \(C20\) must be"),
        (lambda: ReducedPolynomialParameters(1.0, K=1.0), "coefficients must be a sequence"),
        (lambda: GentParameters(mu=-1.0, Jm=1.0, K=1.0), "GentParameters: mu must be"),
        (lambda: GentParameters(mu=1.0, Jm=0.0, K=1.0), "GentParameters: Jm must be"),
        (lambda: GentParameters(mu=1.0, Jm=1.0, K=1.0, lock_fraction=1.0), "GentParameters: lock_fraction"),
        (lambda: ArrudaBoyceParameters(mu=1.0, lambda_m=1.0, K=1.0), "ArrudaBoyceParameters: lambda_m must be"),
        (lambda: ArrudaBoyceParameters(mu=float("inf"), lambda_m=3.0, K=1.0), "ArrudaBoyceParameters: mu must be"),
        (lambda: VerondaWestmannParameters(c1=1.0, c2=0.0, K=1.0), "VerondaWestmannParameters: c2 must be"),
        (lambda: VerondaWestmannParameters(c1=True, c2=1.0, K=1.0), "VerondaWestmannParameters: c1 must be"),
    ],
)
def test_invalid_parameters(make, match):
    with pytest.raises(ParameterError, match=match):
        make()


def test_closed_forms_need_the_log_volumetric_law():
    F = ufl.Identity(3)
    with pytest.raises(ParameterError, match="gent_stress: closed form"):
        gent_stress(F, GentParameters(mu=1.0, Jm=5.0, K=1.0, volumetric="quadratic"))


# --------------------------------------------------------------------------
# Taylor tests on a small box (MPI.COMM_WORLD)
# --------------------------------------------------------------------------
STEPS = 2e-2 / 2.0 ** np.arange(5)


@pytest.mark.parametrize("name", ["yeoh", "gent", "arruda_boyce", "veronda_westmann"])
def test_taylor_energy_residual_tangent(name):
    law = LAWS[name]
    r0, r1 = taylor_rates(lambda mesh: lambda F: law.psi(F, law.params), STEPS)
    assert r0.min() > 1.9 and r0.max() < 2.1, r0
    assert r1.min() > 1.9, r1
