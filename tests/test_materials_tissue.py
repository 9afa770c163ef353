r"""Verification of the fibre-reinforced tissue laws: Holzapfel–Gasser–Ogden, Weiss (ligament), Fung orthotropic.

Each law is compiled once into a :class:`dolfinx.fem.Expression` on a one-cell
mesh (``MPI.COMM_SELF``; every rank checks independently) whose deformation
gradient, rotations and fibre directions are :class:`dolfinx.fem.Constant`\ s,
returning :math:`\psi(F; a)`, :math:`\psi(QF; a)`, :math:`\psi(FR^T; Ra)`, the
isochoric part, UFL's :math:`\partial\psi/\partial F`, the closed-form :math:`P`
and UFL's tangent. Independent references are NumPy transcriptions of the
published energies; incompressible uniaxial nominal stresses along a fibre axis
:math:`N = dW/d\lambda` (transverse isotropy about the stretch axis makes
:math:`F = \operatorname{diag}(\lambda, \lambda^{-1/2}, \lambda^{-1/2})` laterally
traction free, and :math:`N = P_{11} - \lambda^{-3/2}P_{22}`) are taken by
complex-step differentiation of the NumPy energy, or from the law's closed-form
fibre stress (Weiss).

Objectivity is :math:`\psi(QF; a) = \psi(F; a)` (a spatial rotation leaves the
reference fibres alone) and :math:`\psi(FR^T; Ra) = \psi(F; a)` (rotating the
reference configuration rotates the fibres with it). Material symmetry:
:math:`\psi(FR^T; a) = \psi(F; a)` for rotations :math:`R` about the fibre
(Weiss), by :math:`\pi` about a material axis (Fung), and by :math:`\pi` about
the bisector of the two families, which swaps them (HGO).

Taylor tests (energy → residual → tangent) run on a small box on
``MPI.COMM_WORLD`` with fibre fields from :func:`hyperfem.fibres.constant_fibres`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
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
from hyperfem.fibres import constant_fibres
from hyperfem.materials.fung import (
    FungOrthotropicParameters,
    fung_orthotropic,
    fung_orthotropic_isochoric,
    fung_orthotropic_stress,
)
from hyperfem.materials.holzapfel_gasser_ogden import (
    HolzapfelGasserOgdenParameters,
    holzapfel_gasser_ogden,
    holzapfel_gasser_ogden_isochoric,
    holzapfel_gasser_ogden_stress,
)
from hyperfem.materials.weiss import WeissParameters, weiss, weiss_isochoric, weiss_stress

JIT_OPTIONS = {"timeout": 300}
K = 20.0
EX = np.array([1.0, 0.0, 0.0])
EY = np.array([0.0, 1.0, 0.0])
A2 = np.array([math.cos(math.pi / 6), math.sin(math.pi / 6), 0.0])  # second HGO family / Fung axis


@dataclass(frozen=True)
class Law:
    """A law under test: ``psi(F, a1, a2, params)``, its isochoric part and closed form; a NumPy energy."""

    psi: Callable[..., Any]
    iso: Callable[..., Any]
    stress: Callable[..., Any]
    params: Any
    W: Callable[[np.ndarray, np.ndarray, np.ndarray], Any]  # isochoric energy of (F, a1, a2), complex-safe
    a2: np.ndarray  # default second direction


# --------------------------------------------------------------------------
# NumPy references (complex-safe for complex-step derivatives)
# --------------------------------------------------------------------------
def _iso_invariants(F, a1, a2):
    C = F.T @ F
    Jm23 = np.linalg.det(F) ** (-2.0 / 3.0)
    I2 = 0.5 * (np.trace(C) ** 2 - np.trace(C @ C))
    return Jm23 * np.trace(C), Jm23**2 * I2, Jm23 * (a1 @ C @ a1), Jm23 * (a2 @ C @ a2)


def _H(y):
    """Smooth step 1/2 (1 + tanh y), clamped at |y| = 30 like the module."""
    if y.real >= 30:
        return 1.0
    if y.real <= -30:
        return 0.0
    return 0.5 * (1.0 + np.tanh(y))


def _hgo_W(p: HolzapfelGasserOgdenParameters):
    def g(x):
        return p.k1 / (2 * p.k2) * (np.exp(p.k2 * x * x) - 1.0)

    def fibre(I1, I4):
        E = p.kappa * (I1 - 3.0) + (1.0 - 3.0 * p.kappa) * (I4 - 1.0)
        eps = p.smoothing
        if p.switch == "none":
            return g(E)
        if p.switch == "strain":
            return g(E * _H(E / eps)) if eps > 0 else (g(E) if E.real > 0 else 0.0)
        return _H((I4 - 1.0) / eps) * g(E) if eps > 0 else (g(E) if I4.real > 1 else 0.0)

    def W(F, a1, a2):
        I1, _, I4, I6 = _iso_invariants(F, a1, a2)
        return 0.5 * p.mu * (I1 - 3.0) + fibre(I1, I4) + fibre(I1, I6)

    return W


def _weiss_sigma(lam, p: WeissParameters):
    """The published fibre stress lam dF2/dlam."""
    if lam <= 1.0:
        return 0.0
    if lam < p.lambda_star:
        return p.c3 * math.expm1(p.c4 * (lam - 1.0))
    return p.c5 * lam + p.c6


def _weiss_F2(lam, p: WeissParameters, n: int = 4000):
    """F2 by composite Simpson on [1, min(lam, lam*)] plus the linear branch (a method independent of the module's)."""
    if lam <= 1.0:
        return 0.0
    top = min(lam, p.lambda_star)
    t = np.linspace(1.0, top, n + 1)
    f = np.expm1(p.c4 * (t - 1.0)) / t
    toe = p.c3 * (top - 1.0) / (3 * n) * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum())
    if lam <= p.lambda_star:
        return toe
    return toe + p.c5 * (lam - p.lambda_star) + p.c6 * math.log(lam / p.lambda_star)


def _weiss_W(p: WeissParameters):
    def W(F, a1, _a2):
        I1, I2, I4, _ = _iso_invariants(F, a1, a1)
        return p.c1 * (I1 - 3.0) + p.c2 * (I2 - 3.0) + _weiss_F2(math.sqrt(I4), p)

    return W


def _fung_W(p: FungOrthotropicParameters):
    L = np.array(p.normal_block)

    def W(F, a1, a2):
        C = F.T @ F
        Et = 0.5 * (np.linalg.det(F) ** (-2.0 / 3.0) * C - np.eye(3))
        R = np.column_stack([a1, a2, np.cross(a1, a2)])
        E = R.T @ Et @ R
        d = np.diag(E)
        Q = d @ L @ d + 2 * (p.b7 * E[0, 1] ** 2 + p.b8 * E[1, 2] ** 2 + p.b9 * E[2, 0] ** 2)
        return 0.5 * p.c * (np.exp(Q) - 1.0)

    return W


HGO = HolzapfelGasserOgdenParameters(mu=1.0, k1=2.0, k2=0.8, kappa=0.1, K=K)
WEISS = WeissParameters(c1=1.0, c2=0.2, c3=0.05, c4=20.0, c5=10.0, lambda_star=1.1, K=K)
FUNG = FungOrthotropicParameters(c=1.0, b1=2.0, b2=1.5, b3=1.0, b4=0.5, b5=0.3, b6=0.4, b7=1.2, b8=0.9, b9=0.8, K=K)


def _hgo(p):
    return Law(
        holzapfel_gasser_ogden, holzapfel_gasser_ogden_isochoric, holzapfel_gasser_ogden_stress, p, _hgo_W(p), A2
    )


def _weiss_psi(F, a1, _a2, p):
    return weiss(F, a1, p)


def _weiss_iso(F, a1, _a2, p):
    return weiss_isochoric(F, a1, p)


def _weiss_closed(F, a1, _a2, p):
    return weiss_stress(F, a1, p)


LAWS = {
    "hgo_strain": _hgo(HGO),
    "hgo_strain_smooth": _hgo(replace(HGO, smoothing=0.02)),
    "hgo_stretch": _hgo(replace(HGO, switch="stretch")),
    "hgo_stretch_smooth": _hgo(replace(HGO, switch="stretch", smoothing=0.02)),
    "weiss": Law(_weiss_psi, _weiss_iso, _weiss_closed, WEISS, _weiss_W(WEISS), EY),
    "fung": Law(fung_orthotropic, fung_orthotropic_isochoric, fung_orthotropic_stress, FUNG, _fung_W(FUNG), EY),
}


# --------------------------------------------------------------------------
# Point evaluation
# --------------------------------------------------------------------------
class _Evaluator:
    def __init__(self, name: str):
        law = LAWS[name]
        self.mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
        c = {k: fem.Constant(self.mesh, np.eye(3)) for k in ("F", "Q", "R", "M")}
        c.update({k: fem.Constant(self.mesh, EX.copy()) for k in ("a1", "a2", "a1r", "a2r")})
        c["t"] = fem.Constant(self.mesh, 0.0)
        self.c = c
        # F = F0 + t M with t = 0: dP/dt is the tangent applied to M, A : M (cheaper to compile than all of A)
        t = ufl.variable(c["t"])
        F = ufl.variable(c["F"] + t * c["M"])
        psi = law.psi(F, c["a1"], c["a2"], law.params)
        P = ufl.diff(psi, F)
        dP = ufl.diff(P, t)
        scalars = [
            psi,
            law.psi(c["Q"] * c["F"], c["a1"], c["a2"], law.params),
            law.psi(c["F"] * c["R"].T, c["a1r"], c["a2r"], law.params),
            law.iso(F, c["a1"], c["a2"], law.params),
        ]
        P_closed = law.stress(c["F"], c["a1"], c["a2"], law.params)
        entries = scalars + [P[i] for i in np.ndindex(3, 3)] + [P_closed[i] for i in np.ndindex(3, 3)]
        entries += [dP[i] for i in np.ndindex(3, 3)]
        self.expr = fem.Expression(ufl.as_vector(entries), np.array([[0.25, 0.25, 0.25]]), jit_options=JIT_OPTIONS)
        self.default_a2 = law.a2

    def __call__(self, F, a1=EX, a2=None, Q=None, R=None, a1r=None, a2r=None, M=None) -> dict:
        a2 = self.default_a2 if a2 is None else a2
        R = np.eye(3) if R is None else R
        values = {
            "F": F,
            "Q": np.eye(3) if Q is None else Q,
            "R": R,
            "a1": a1,
            "a2": a2,
            "a1r": R @ a1 if a1r is None else a1r,
            "a2r": R @ a2 if a2r is None else a2r,
            "M": np.zeros((3, 3)) if M is None else M,
        }
        for k, v in values.items():
            self.c[k].value[:] = v
        v = self.expr.eval(self.mesh, np.array([0], dtype=np.int32)).reshape(-1)
        return {
            "psi": v[0],
            "psi_QF": v[1],
            "psi_rotref": v[2],
            "psi_iso": v[3],
            "P": v[4:13].reshape(3, 3),
            "P_closed": v[13:22].reshape(3, 3),
            "A:M": v[22:].reshape(3, 3),
        }


@cache
def evaluator(name: str) -> _Evaluator:
    return _Evaluator(name)


def random_F(rng, scale=0.3):
    while True:
        F = np.eye(3) + scale * rng.standard_normal((3, 3))
        if np.linalg.det(F) > 0.2:
            return F


def random_rotation(rng):
    while True:
        Q, R = np.linalg.qr(rng.standard_normal((3, 3)))
        Q = Q @ np.diag(np.sign(np.diag(R)))
        if np.linalg.det(Q) < 0:
            Q[:, 0] *= -1
        if np.linalg.norm(Q - np.eye(3)) > 0.5:
            return Q


def rotation(axis, angle):
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    Kx = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * Kx + (1 - math.cos(angle)) * Kx @ Kx


def states() -> list[np.ndarray]:
    """Random gradients plus large ones: uniaxial to lambda = 3 along and across x, shear 1.5, compression."""
    rng = np.random.default_rng(31)
    out = [random_F(rng) for _ in range(5)]
    out.append(np.diag([3.0, 3.0**-0.5, 3.0**-0.5]) @ rotation([0.1, 0.2, 1.0], 0.3) * 1.04)
    out.append(np.diag([3.0**-0.5, 3.0, 3.0**-0.5]) * 0.97)
    shear = np.eye(3)
    shear[0, 1] = 1.5
    out.append(shear @ np.diag([1.1, 0.95, 1.0]))
    out.append(random_rotation(rng) @ np.diag([0.6, 1.2, 1.3]))
    return out


def neo_hookean_matrix_P(F, mu):
    """P of mu/2 (I1bar - 3) + K/2 ln(J)^2 (the HGO matrix with U)."""
    J = np.linalg.det(F)
    Finv_T = np.linalg.inv(F).T
    return mu * J ** (-2 / 3) * (F - np.trace(F.T @ F) / 3 * Finv_T) + K * math.log(J) * Finv_T


def unit(a, b):
    M = np.zeros((3, 3))
    M[a, b] = 1.0
    return M


def complex_step(f, x, h=1e-30):
    return f(x + 1j * h).imag / h


# --------------------------------------------------------------------------
# Generic checks of every law
# --------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(LAWS))
def test_stress_free_reference_and_finite_tangent(name):
    rng = np.random.default_rng(4)
    for M in (rng.standard_normal((3, 3)), rng.standard_normal((3, 3))):  # generic: every entry of A enters A : M
        v = evaluator(name)(np.eye(3), M=M)
        assert abs(v["psi"]) < 1e-14
        assert np.max(np.abs(v["P"])) < 1e-13 and np.max(np.abs(v["P_closed"])) < 1e-13
        assert np.all(np.isfinite(v["A:M"])) and np.max(np.abs(v["A:M"])) > 0.1


@pytest.mark.parametrize("name", list(LAWS))
def test_energy_matches_numpy(name):
    law, ev = LAWS[name], evaluator(name)
    for F in states():
        v = ev(F)
        expected = law.W(F, EX, law.a2)
        assert v["psi_iso"] == pytest.approx(expected, rel=1e-11)
        assert v["psi"] == pytest.approx(expected + 0.5 * K * math.log(np.linalg.det(F)) ** 2, rel=1e-11)


@pytest.mark.parametrize("name", list(LAWS))
def test_ufl_stress_matches_closed_form(name):
    ev = evaluator(name)
    worst = 0.0
    for F in states():
        v = ev(F)
        scale = np.max(np.abs(v["P_closed"]))
        assert np.all(np.isfinite(v["P"])) and scale > 0.05
        worst = max(worst, np.max(np.abs(v["P"] - v["P_closed"])) / scale)
    assert worst < 1e-12, worst


@pytest.mark.parametrize("name", list(LAWS))
def test_objectivity(name):
    """psi(QF; a) = psi(F; a) and psi(F R^T; R a) = psi(F; a) for random rotations Q, R."""
    ev = evaluator(name)
    rng = np.random.default_rng(8)
    for F in states():
        v = ev(F, Q=random_rotation(rng), R=random_rotation(rng))
        assert v["psi_QF"] == pytest.approx(v["psi"], rel=1e-12)
        assert v["psi_rotref"] == pytest.approx(v["psi"], rel=1e-12)


@pytest.mark.parametrize(
    "name, R",
    [
        ("weiss", rotation(EX, 0.7)),  # transverse isotropy about the fibre
        ("weiss", rotation(EX, 2.9)),
        ("fung", rotation(EX, math.pi)),  # orthotropy: pi about each material axis
        ("fung", rotation(EY, math.pi)),
        ("fung", rotation(np.cross(EX, EY), math.pi)),
        ("hgo_strain", rotation(EX + A2, math.pi)),  # swaps the two families
        ("hgo_stretch_smooth", rotation(EX + A2, math.pi)),
    ],
)
def test_material_symmetry(name, R):
    """psi(F R^T; a) = psi(F; a) with the directions kept (the rotation is a symmetry of the material)."""
    law, ev = LAWS[name], evaluator(name)
    a2 = A2 if name.startswith("hgo") else law.a2
    for F in states():
        v = ev(F, a2=a2, R=R, a1r=EX, a2r=a2)
        assert v["psi_rotref"] == pytest.approx(v["psi"], rel=1e-12)


# --------------------------------------------------------------------------
# HGO: tension-only switch, uniaxial along and across the fibres, reference tangent
# --------------------------------------------------------------------------
HGO_NAMES = ["hgo_strain", "hgo_strain_smooth", "hgo_stretch", "hgo_stretch_smooth"]


def _uniaxial(lam, axis=0):
    d = np.full(3, lam**-0.5)
    d[axis] = lam
    return np.diag(d)


@pytest.mark.parametrize("name", HGO_NAMES)
def test_hgo_uniaxial_along_the_fibres(name):
    """Both families along x, stretch along x: N = dW/dlam (complex step of the NumPy energy)."""
    law, ev = LAWS[name], evaluator(name)
    for lam in (1.1, 1.5, 2.0, 3.0):
        P = ev(_uniaxial(lam), a1=EX, a2=EX)["P"]
        N = complex_step(lambda s: law.W(_uniaxial(s), EX, EX), lam)
        assert P[1, 1] == pytest.approx(P[2, 2], rel=1e-13)
        assert P[0, 0] - lam**-1.5 * P[1, 1] == pytest.approx(N, rel=1e-11)
        assert N > 2.0 * (lam - lam**-2)  # well above the matrix alone (mu = 1)


@pytest.mark.parametrize("name", ["hgo_strain", "hgo_stretch"])
def test_hgo_across_the_fibres_no_fibre_stress(name):
    """Fibres along x, stretch along y: the fibres shorten (I4 = 1/lam < 1) and carry nothing, N = mu (lam - lam^-2)."""
    ev = evaluator(name)
    for lam in (1.2, 1.5, 2.0):  # kappa = 0.1: E < 0 as well up to lam = 2
        F = _uniaxial(lam, axis=1)
        P = ev(F, a1=EX, a2=EX)["P"]
        np.testing.assert_allclose(P, neo_hookean_matrix_P(F, HGO.mu), rtol=0, atol=1e-13 * np.max(np.abs(P)))
        assert P[1, 1] - lam**-1.5 * P[0, 0] == pytest.approx(HGO.mu * (lam - lam**-2), rel=1e-12)


def test_hgo_switches_differ_for_compressed_dispersed_fibres():
    """At lam = 3 across the fibres E = kappa (I1 - 3) + (1 - 3 kappa)(I4 - 1) = +0.2 although I4 = 1/3:
    the "strain" switch (FEBio's E >= 0) loads the compressed fibres, the "stretch" switch (I4 > 1) does not."""
    F = _uniaxial(3.0, axis=1)
    I1, I4 = 9.0 + 2.0 / 3.0, 1.0 / 3.0
    assert HGO.kappa * (I1 - 3) + (1 - 3 * HGO.kappa) * (I4 - 1) == pytest.approx(0.2)
    matrix = neo_hookean_matrix_P(F, HGO.mu)
    strain = evaluator("hgo_strain")(F, a1=EX, a2=EX)["P"]
    stretch = evaluator("hgo_stretch")(F, a1=EX, a2=EX)["P"]
    assert np.max(np.abs(strain - matrix)) > 0.1
    np.testing.assert_allclose(stretch, matrix, rtol=0, atol=1e-13 * np.max(np.abs(matrix)))


def _path(t):
    """A non-trivial path through E = 0 for fibres along x: stretch t along x with shear and lateral stretch."""
    S = np.eye(3)
    S[0, 1], S[1, 2] = 0.3, -0.2
    return np.diag([t, 1.15, 1.0 / (1.15 * t)]) @ S


def _fibre_E(F, kappa=HGO.kappa):
    I1, _, I4, _ = _iso_invariants(F, EX, EX)
    return kappa * (I1 - 3) + (1 - 3 * kappa) * (I4 - 1)


def _root(f, lo, hi):
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(lo) * f(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def _dpsi_dt(ev, t, h=1e-7):
    """psi and d psi/dt = P : dF/dt along the path (dF/dt by central differences of the path)."""
    v = ev(_path(t), a1=EX, a2=EX)
    return v["psi"], float(np.sum(v["P"] * (_path(t + h) - _path(t - h)) / (2 * h)))


def test_hgo_strain_switch_both_sides_and_c1():
    """Exact 'strain' switch along a path through E = 0: no fibre stress on the compressive side, fibre stress on
    the tensile side, energy and its derivative continuous (C^1) across."""
    ev = evaluator("hgo_strain")
    t0 = _root(lambda t: _fibre_E(_path(t)), 0.5, 1.5)
    for d in (1e-2, 1e-3):
        F_minus, F_plus = _path(t0 - d), _path(t0 + d)
        assert _fibre_E(F_minus) < 0 < _fibre_E(F_plus)
        P_minus = ev(F_minus, a1=EX, a2=EX)["P"]
        np.testing.assert_allclose(P_minus, neo_hookean_matrix_P(F_minus, HGO.mu), rtol=0, atol=1e-13)
        assert np.max(np.abs(ev(F_plus, a1=EX, a2=EX)["P"] - neo_hookean_matrix_P(F_plus, HGO.mu))) > 1e-6
    jumps = []
    for d in (1e-4, 1e-5, 1e-6):
        (psi_m, dpsi_m), (psi_p, dpsi_p) = _dpsi_dt(ev, t0 - d), _dpsi_dt(ev, t0 + d)
        jumps.append(abs(dpsi_p - dpsi_m))
        assert abs(psi_p - psi_m) < 3 * d * max(abs(dpsi_m), 1.0)  # continuous energy
    # the derivative's jump shrinks with d (no jump in the limit): C^1
    assert jumps[-1] < 1e-4 and jumps[0] / jumps[-1] > 50, jumps


def test_hgo_stretch_switch_energy_jump_with_dispersion():
    """'stretch' switch with kappa > 0: at I4 = 1 the energy jumps by 2 g(kappa (I1 - 3)) (two families); with
    smoothing the jump is spread over a width epsilon and the energy is continuous."""
    ev = evaluator("hgo_stretch")
    t0 = _root(lambda t: _iso_invariants(_path(t), EX, EX)[2] - 1.0, 0.5, 1.5)
    I1 = _iso_invariants(_path(t0), EX, EX)[0]
    p = HGO
    jump_expected = 2 * p.k1 / (2 * p.k2) * math.expm1(p.k2 * (p.kappa * (I1 - 3)) ** 2)
    d = 1e-9
    jump = ev(_path(t0 + d), a1=EX, a2=EX)["psi"] - ev(_path(t0 - d), a1=EX, a2=EX)["psi"]
    assert jump == pytest.approx(jump_expected, rel=1e-6)
    smooth = evaluator("hgo_stretch_smooth")
    assert abs(smooth(_path(t0 + d), a1=EX, a2=EX)["psi"] - smooth(_path(t0 - d), a1=EX, a2=EX)["psi"]) < 1e-6


@pytest.mark.parametrize("name", ["hgo_strain_smooth", "hgo_stretch_smooth"])
def test_hgo_smoothing_is_exact_away_from_the_switch(name):
    """|switch variable| >= 20 epsilon: the smoothed law is the exact one (tanh(20) = 1 - 8e-18), in tension
    (lam = 1.6 along the fibres: E = 1.17, I4 - 1 = 1.56) and in compression (lam = 0.5: E = -0.4, I4 - 1 = -0.75)."""
    exact = evaluator(name.replace("_smooth", ""))
    ev = evaluator(name)
    for F in (_uniaxial(1.6), _uniaxial(0.5)):
        a, b = ev(F, a1=EX, a2=EX), exact(F, a1=EX, a2=EX)
        assert a["psi"] == pytest.approx(b["psi"], rel=1e-14)
        np.testing.assert_allclose(a["P"], b["P"], rtol=0, atol=1e-14 * np.max(np.abs(b["P"])))


@pytest.mark.parametrize("name, d2", [("hgo_strain_smooth", 0.25), ("hgo_stretch_smooth", 0.5)])
def test_hgo_reference_tangent(name, d2):
    """At F = I: A_0101 = mu (shear in the fibre plane; the fibres do not stretch), and with smoothing
    A_0000 = K + 4 mu/3 + 2 d2 k1 (dE/dF00)^2, dE/dF00 = 4/3 (1 - 3 kappa), d2 = H(0)^2 or H(0)."""
    ev = evaluator(name)
    p = LAWS[name].params
    assert ev(np.eye(3), a1=EX, a2=EX, M=unit(0, 1))["A:M"][0, 1] == pytest.approx(p.mu, rel=1e-12)
    dE = 4.0 / 3.0 * (1 - 3 * p.kappa)
    A0000 = ev(np.eye(3), a1=EX, a2=EX, M=unit(0, 0))["A:M"][0, 0]
    assert A0000 == pytest.approx(K + 4 * p.mu / 3 + 2 * d2 * p.k1 * dE**2, rel=1e-12)


# --------------------------------------------------------------------------
# Weiss: toe and linear regions, continuity at lambda*, Ei closed form
# --------------------------------------------------------------------------
def test_weiss_uniaxial_along_and_across_the_fibre():
    ev = evaluator("weiss")
    p = WEISS
    for lam in (1.03, 1.08, 1.1, 1.3, 2.0, 3.0):  # toe, toe, lambda*, linear
        P = ev(_uniaxial(lam), a1=EX)["P"]
        N = 2 * (lam - lam**-2) * (p.c1 + p.c2 / lam) + _weiss_sigma(lam, p) / lam
        assert P[0, 0] - lam**-1.5 * P[1, 1] == pytest.approx(N, rel=1e-11)
    for lam in (1.3, 2.0):  # across: fibre shortened, no fibre stress
        P = ev(_uniaxial(lam, axis=1), a1=EX)["P"]
        assert P[1, 1] - lam**-1.5 * P[0, 0] == pytest.approx(2 * (lam - lam**-2) * (p.c1 + p.c2 / lam), rel=1e-12)


def test_weiss_fibre_stress_continuous_at_lambda_star():
    p = WEISS
    left, right = _weiss_sigma(p.lambda_star * (1 - 1e-12), p), _weiss_sigma(p.lambda_star, p)
    assert right == pytest.approx(left, rel=1e-9)
    ev = evaluator("weiss")
    d = 1e-8
    Pl = ev(_uniaxial(p.lambda_star - d), a1=EX)["P"]
    Pr = ev(_uniaxial(p.lambda_star + d), a1=EX)["P"]
    assert np.max(np.abs(Pr - Pl)) < 1e-5 * np.max(np.abs(Pl))


def test_weiss_energy_matches_the_exponential_integral_form():
    """F2 = c3 [e^-c4 (Ei(c4 lam) - Ei(c4)) - ln lam] in the toe region (FEBio's closed form)."""
    special = pytest.importorskip("scipy.special")
    p = WEISS
    ev = evaluator("weiss")
    for lam in (1.02, 1.05, 1.1, 1.4):
        top = min(lam, p.lambda_star)
        F2 = p.c3 * (math.exp(-p.c4) * (special.expi(p.c4 * top) - special.expi(p.c4)) - math.log(top))
        if lam > p.lambda_star:
            F2 += p.c5 * (lam - p.lambda_star) + p.c6 * math.log(lam / p.lambda_star)
        I1, I2 = lam**2 + 2 / lam, 2 * lam + lam**-2
        assert ev(_uniaxial(lam), a1=EX)["psi_iso"] - p.c1 * (I1 - 3) - p.c2 * (I2 - 3) == pytest.approx(F2, rel=1e-9)


def test_weiss_shear_modulus():
    A0101 = evaluator("weiss")(np.eye(3), a1=EX, M=unit(0, 1))["A:M"][0, 1]
    assert A0101 == pytest.approx(WEISS.shear_modulus, rel=1e-12)


# --------------------------------------------------------------------------
# Fung: uniaxial, shear moduli, isotropic case
# --------------------------------------------------------------------------
def test_fung_uniaxial_along_a1():
    """Stretch lam along a1 = x; lambda_2 solved for sigma_22 = sigma_33 (lateral faces traction free, lambda_3 =
    1/(lam lambda_2)); then N = (sigma_11 - sigma_33)/lam = P11 - P33 lambda_3/lam is dW/dlam at fixed lambda_2."""
    law, ev = LAWS["fung"], evaluator("fung")

    def state(lam, l2):
        return np.diag([lam, l2, 1.0 / (lam * l2)])

    def lateral(lam, l2):  # sigma_22 - sigma_33 (J = 1: sigma_ii = P_ii lambda_i)
        P = ev(state(lam, l2), a1=EX, a2=EY)["P"]
        return P[1, 1] * l2 - P[2, 2] / (lam * l2)

    for lam in (0.7, 1.2, 1.6, 2.5):
        l2 = _root(lambda x, lam=lam: lateral(lam, x), 0.4 * lam**-0.5, 2.5 * lam**-0.5)
        F = state(lam, l2)
        P = ev(F, a1=EX, a2=EY)["P"]
        assert abs(lateral(lam, l2)) < 1e-10 * np.max(np.abs(P))
        assert abs(l2 - lam**-0.5) > 1e-3  # orthotropic: the lateral stretches differ
        N = complex_step(lambda s, l2=l2: law.W(state(s, l2), EX, EY), lam)
        assert P[0, 0] - P[2, 2] * F[2, 2] / lam == pytest.approx(N, rel=1e-11)


def test_fung_shear_moduli():
    """A_abab at F = I in the material axes x, y, z are the documented G12, G23, G31 = c b/2."""
    ev = evaluator("fung")
    for (a, b), G in zip(((0, 1), (1, 2), (2, 0)), FUNG.shear_moduli, strict=True):
        assert ev(np.eye(3), a1=EX, a2=EY, M=unit(a, b))["A:M"][a, b] == pytest.approx(G, rel=1e-12)


def test_fung_isotropic_case():
    p = FungOrthotropicParameters.isotropic(c=2.0, mu=0.7, lmbda=1.5, K=K)
    assert p.shear_moduli == pytest.approx((0.7, 0.7, 0.7), rel=1e-15)
    rng = np.random.default_rng(3)
    W = _fung_W(p)
    F = random_F(rng)
    Q, R = random_rotation(rng), random_rotation(rng)
    # isotropic: independent of the axes
    assert W(F, Q[:, 0], Q[:, 1]) == pytest.approx(W(F, R[:, 0], R[:, 1]), rel=1e-12)


# --------------------------------------------------------------------------
# Parameter validation
# --------------------------------------------------------------------------
def _fung(**kw):
    base = dict(c=1.0, b1=2.0, b2=1.5, b3=1.0, b4=0.5, b5=0.3, b6=0.4, b7=1.2, b8=0.9, b9=0.8, K=1.0)
    base.update(kw)
    return FungOrthotropicParameters(**base)


def _weiss(**kw):
    base = dict(c1=1.0, c2=0.0, c3=0.1, c4=10.0, c5=5.0, lambda_star=1.05, K=1.0)
    base.update(kw)
    return WeissParameters(**base)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: replace(HGO, mu=0.0), "HolzapfelGasserOgdenParameters: mu must be"),
        (lambda: replace(HGO, k1=-1.0), "HolzapfelGasserOgdenParameters: k1 must be"),
        (lambda: replace(HGO, k2=0.0), "HolzapfelGasserOgdenParameters: k2 must be"),
        (lambda: replace(HGO, kappa=0.4), r"HolzapfelGasserOgdenParameters: kappa must be a number in \[0, 1/3\]"),
        (lambda: replace(HGO, switch="tension"), "HolzapfelGasserOgdenParameters: switch must be one of"),
        (lambda: replace(HGO, smoothing=-0.1), "HolzapfelGasserOgdenParameters: smoothing must be"),
        (lambda: replace(HGO, volumetric="cubic"), "unknown volumetric law"),
        (lambda: _weiss(c1=0.0), "WeissParameters: c1 must be"),
        (lambda: _weiss(c3=-1.0), "WeissParameters: c3 must be"),
        (lambda: _weiss(c4=0.0), "WeissParameters: c4 must be"),
        (lambda: _weiss(lambda_star=1.0), "WeissParameters: lambda_star must be a finite number > 1"),
        (lambda: _fung(c=0.0), "FungOrthotropicParameters: c must be"),
        (lambda: _fung(b7=0.0), "FungOrthotropicParameters: b7 must be"),
        (lambda: _fung(b4=float("nan")), "FungOrthotropicParameters: b4 must be"),
        (lambda: _fung(b4=3.0), "FungOrthotropicParameters: the normal block .* must be positive definite"),
    ],
)
def test_invalid_parameters(make, match):
    with pytest.raises(ParameterError, match=match):
        make()


def test_weiss_c6_and_quadrature():
    p = WEISS
    assert p.c6 == pytest.approx(p.c3 * math.expm1(p.c4 * (p.lambda_star - 1)) - p.c5 * p.lambda_star, rel=1e-15)
    assert p.quadrature_points == 8 + math.ceil(24.0 * 0.1)


# --------------------------------------------------------------------------
# Taylor tests on a small box (MPI.COMM_WORLD), fibre fields from hyperfem.fibres
# --------------------------------------------------------------------------
STEPS = 5e-3 / 2.0 ** np.arange(5)


WEISS_TOE = replace(WEISS, lambda_star=1.5)  # the Taylor state (lambda ~ 1.1-1.35) lies inside the toe region
TAYLOR = {
    "hgo_strain": lambda F, a1, a2: holzapfel_gasser_ogden(F, a1, a2, HGO),
    "hgo_stretch_smooth": lambda F, a1, a2: holzapfel_gasser_ogden(F, a1, a2, LAWS["hgo_stretch_smooth"].params),
    "weiss_toe": lambda F, a1, a2: weiss(F, a1, WEISS_TOE),
    "fung": lambda F, a1, a2: fung_orthotropic(F, a1, ufl.cross(ufl.as_vector([0.0, 0.0, 1.0]), a1), FUNG),
}


STRETCH = {"hgo_stretch_smooth": 0.0, "weiss_toe": 0.2}


@pytest.mark.parametrize("name", list(TAYLOR))
def test_taylor_energy_residual_tangent(name):
    # the smoothed switch is tested where it acts: fibres unstretched on average, |I4 - 1| ~ 0.1 = 5 epsilon
    psi = TAYLOR[name]

    def density(mesh):
        a1, a2 = constant_fibres(mesh, EX, "DG0"), constant_fibres(mesh, A2, "DG0")
        return lambda F: psi(F, a1, a2)

    r0, r1 = taylor_rates(density, STEPS, stretch=STRETCH.get(name, 0.3), amplitude=0.04)
    assert r0.min() > 1.9 and r0.max() < 2.1, r0
    assert r1.min() > 1.9, r1
