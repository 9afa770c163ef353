r"""The muscle/tendon energy: parameters, force–length curves, stresses, symmetries,
and a homogeneous fibre-direction stretch of a unit cube against the analytic nominal stress.

Material-point checks evaluate UFL expressions of constant tensors with one
compiled :class:`dolfinx.fem.Expression` each (the values are Constants, so
every random sample reuses the same kernel).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.errors import ParameterError
from hyperfem.loading import Activation
from hyperfem.materials.mooney_rivlin import MooneyRivlinParameters, mooney_rivlin, mooney_rivlin_stress
from hyperfem.materials.muscle import (
    MuscleParameters,
    force_length_active,
    force_length_active_integral,
    force_length_passive,
    force_length_passive_integral,
    isochoric_fibre_stretch,
    muscle,
    muscle_stress,
    transversely_isotropic,
)
from hyperfem.materials.volumetric import VOLUMETRIC_LAWS, volumetric_energy
from hyperfem.simulation.reactions import ReactionForce

RNG = np.random.default_rng(20240603)


# -- numpy references, written independently of the UFL code ---------------------------
def f_act_ref(ell):
    ell = np.asarray(ell, dtype=float)
    return np.select(
        [(ell > 0.4) & (ell <= 0.6), (ell > 0.6) & (ell < 1.4), (ell >= 1.4) & (ell < 1.6)],
        [9 * (ell - 0.4) ** 2, 1 - 4 * (1 - ell) ** 2, 9 * (ell - 1.6) ** 2],
        0.0,
    )


def f_pas_ref(ell, P1=0.05, P2=6.6, ls=1.4):
    ell = np.asarray(ell, dtype=float)
    fs = P1 * (math.exp(P2 * (ls - 1)) - 1)
    dfs = P1 * P2 * math.exp(P2 * (ls - 1))
    return np.where(
        ell <= 1, 0.0, np.where(ell < ls, P1 * (np.exp(P2 * (np.minimum(ell, ls) - 1)) - 1), fs + dfs * (ell - ls))
    )


def integral_ref(f, ell, n=20001):
    """Trapezoidal integral of f from 0 to l (fine grid; reference only)."""
    t = np.linspace(0.0, ell, n)
    y = f(t)
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))


# -- a tiny evaluator of constant-tensor UFL expressions -------------------------------
@pytest.fixture(scope="module")
def point():
    mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    return mesh


class Evaluator:
    """Compile ``build(F, a0, alpha, l)`` once; evaluate it for many constant inputs."""

    def __init__(self, mesh, build):
        self.mesh = mesh
        self.Fc = fem.Constant(mesh, np.eye(3))
        self.a0 = fem.Constant(mesh, np.array([1.0, 0.0, 0.0]))
        self.alpha = fem.Constant(mesh, 0.0)
        self.ell = fem.Constant(mesh, 1.0)
        outputs = build(self.Fc, self.a0, self.alpha, self.ell)
        self.shapes = [o.ufl_shape for o in outputs]
        flat = []
        for o in outputs:
            flat += [o] if o.ufl_shape == () else [o[idx] for idx in np.ndindex(o.ufl_shape)]
        self.expr = fem.Expression(ufl.as_vector(flat), np.array([[0.25, 0.25, 0.25]]))

    def __call__(self, F=None, a0=None, alpha=None, ell=None):
        if F is not None:
            self.Fc.value[:] = F
        if a0 is not None:
            self.a0.value[:] = a0
        if alpha is not None:
            self.alpha.value = alpha
        if ell is not None:
            self.ell.value = ell
        vals = self.expr.eval(self.mesh, np.array([0], dtype=np.int32)).ravel()
        out, k = [], 0
        for shape in self.shapes:
            n = int(np.prod(shape)) if shape else 1
            out.append(vals[k] if not shape else vals[k : k + n].reshape(shape))
            k += n
        return out


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _rotation(axis, angle):
    a = _unit(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


PARAMS = MuscleParameters.muscle(lambda_ofl=1.05)


@pytest.fixture(scope="module")
def muscle_eval(point):
    def build(Fc, a0, alpha, _l):
        F = ufl.variable(Fc)
        W = muscle(F, a0, alpha, PARAMS)
        P = ufl.diff(W, F)
        lbar = ufl.variable(isochoric_fibre_stretch(Fc, a0))
        return [W, P, muscle_stress(F, a0, alpha, PARAMS), lbar]

    return Evaluator(point, build)


# -- parameters and activation ------------------------------------------------------------
def test_presets_match_seed():
    m, t = MuscleParameters.muscle(), MuscleParameters.tendon()
    assert (m.c1, m.c2, m.K, m.T_max) == (30e3, 10e3, 60e3, 80e3)
    assert (t.c1, t.c2, t.K, t.T_max) == (60e3, 10e3, 80e3, 80e3)
    assert (m.lambda_ofl, m.P1, m.P2, m.l_star) == (1.0, 0.05, 6.6, 1.4)
    assert MuscleParameters.muscle(K=1e6).K == 1e6


@pytest.mark.parametrize(
    "kwargs",
    [
        {"c1": 0.0},
        {"c2": -1.0},
        {"K": -5.0},
        {"T_max": float("nan")},
        {"lambda_ofl": 0.0},
        {"P2": 0.0},
        {"l_star": 1.0},
        {"volumetric": "cubic"},
    ],
)
def test_invalid_parameters(kwargs):
    with pytest.raises(ParameterError, match="MuscleParameters|volumetric"):
        MuscleParameters.muscle(**kwargs)


def test_activation_range(point):
    with pytest.raises(ParameterError, match=r"\[0, 1\]"):
        muscle(ufl.Identity(3), ufl.as_vector([1.0, 0, 0]), 1.2, PARAMS)
    with pytest.raises(ParameterError, match=r"\[0, 1\]"):
        Activation(point, -0.1)
    a = Activation(point, lambda t: 2 * t)
    a.update(0.5)
    assert a.value == 1.0
    with pytest.raises(ParameterError, match=r"\[0, 1\]"):
        a.update(0.75)
    with pytest.raises(ParameterError, match=r"\[0, 1\]"):
        Activation(point, 1.0, field=lambda x: 2 * x[0])
    ok = Activation(point, 0.5, field=lambda x: x[0])
    assert ok.field is not None and ok.value == 0.5


def test_volumetric_laws(point):
    """U(1) = U'(1) = 0 and U''(1) = K for every law."""
    K = 7.0

    def build(_F, _a0, _alpha, ell):
        out = []
        for name in sorted(VOLUMETRIC_LAWS):
            J = ufl.variable(ell)
            U = volumetric_energy(J, K, name)
            dU = ufl.diff(U, J)
            out += [U, dU, ufl.diff(dU, J)]
        return out

    ev = Evaluator(point, build)
    vals = np.array(ev(ell=1.0)).reshape(-1, 3)
    np.testing.assert_allclose(vals, np.tile([0.0, 0.0, K], (len(VOLUMETRIC_LAWS), 1)), atol=1e-12)


# -- force–length curves ----------------------------------------------------------------------
def test_force_length_curves(point):
    p = PARAMS

    def build(_F, _a0, _alpha, ell):
        lv = ufl.variable(ell)
        A = force_length_active_integral(lv)
        B = force_length_passive_integral(lv, p.P1, p.P2, p.l_star)
        return [
            force_length_active(lv),
            force_length_passive(lv, p.P1, p.P2, p.l_star),
            A,
            B,
            ufl.diff(A, lv),
            ufl.diff(B, lv),
        ]

    ev = Evaluator(point, build)
    samples = [0.3, 0.4, 0.45, 0.55, 0.6, 0.6001, 0.8, 1.0, 1.1, 1.25, 1.3999, 1.4, 1.45, 1.55, 1.6, 1.7, 2.0]
    for ell in samples:
        fa, fp, A, B, dA, dB = ev(ell=ell)
        assert fa == pytest.approx(float(f_act_ref(ell)), abs=1e-12)
        assert fp == pytest.approx(float(f_pas_ref(ell)), abs=1e-12)
        # closed-form integrals: derivative is the curve, value is the integral
        assert dA == pytest.approx(fa, abs=1e-10) and dB == pytest.approx(fp, abs=1e-10)
        assert A == pytest.approx(integral_ref(f_act_ref, ell), abs=1e-7)
        assert B == pytest.approx(integral_ref(f_pas_ref, ell), abs=1e-7)
    # landmarks of the specification
    assert ev(ell=1.0)[0] == pytest.approx(1.0) and ev(ell=0.6)[0] == pytest.approx(0.36)
    assert ev(ell=1.4)[0] == pytest.approx(0.36) and ev(ell=1.6)[0] == 0.0
    assert ev(ell=0.9)[1] == 0.0  # no passive resistance in compression
    # f_pas is C^1 at l*
    eps = 1e-7
    left = (ev(ell=p.l_star)[1] - ev(ell=p.l_star - eps)[1]) / eps
    right = (ev(ell=p.l_star + eps)[1] - ev(ell=p.l_star)[1]) / eps
    assert left == pytest.approx(right, rel=1e-5)


# -- stresses --------------------------------------------------------------------------------
def test_zero_stress_at_identity(muscle_eval):
    W, P, Pc, _ = muscle_eval(F=np.eye(3), a0=_unit([1, 2, 3]), alpha=0.0)
    assert abs(W) < 1e-9 and np.abs(P).max() < 1e-9 and np.abs(Pc).max() < 1e-9


def test_active_prestress_at_identity(muscle_eval):
    """At F = I the active fibre stress alpha T_max f_act(1/lambda_ofl)/lambda_ofl acts along a0 (deviatorically)."""
    a = _unit([0, 0, 1])
    _, P, _, _ = muscle_eval(F=np.eye(3), a0=a, alpha=1.0)
    ell = 1.0 / PARAMS.lambda_ofl
    sf = PARAMS.T_max * float(f_act_ref(ell)) * ell
    np.testing.assert_allclose(P, sf * (np.outer(a, a) - np.eye(3) / 3), atol=1e-8 * PARAMS.T_max)


@pytest.mark.parametrize("alpha", [0.0, 0.4, 1.0])
def test_ufl_stress_matches_closed_form(muscle_eval, alpha):
    """ufl.diff of the energy equals the seed-style closed-form P, over all branches of the curves."""
    branches = set()
    for stretch in (0.55, 0.8, 1.0, 1.2, 1.5, 1.7):
        for _ in range(3):
            a = _unit(RNG.standard_normal(3))
            Q = _rotation(RNG.standard_normal(3), RNG.uniform(0, np.pi))
            U = stretch * np.outer(a, a) + (np.eye(3) - np.outer(a, a)) / math.sqrt(stretch)
            U = U + 0.02 * RNG.standard_normal((3, 3))
            F = Q @ U
            W, P, Pc, lbar = muscle_eval(F=F, a0=a, alpha=alpha)
            branches.add(int(np.digitize(lbar / PARAMS.lambda_ofl, [0.4, 0.6, 1.0, 1.4, 1.6])))
            np.testing.assert_allclose(P, Pc, rtol=1e-9, atol=1e-9 * np.abs(P).max())
    assert len(branches) >= 5


def test_mooney_rivlin_closed_form(point):
    params = MooneyRivlinParameters(c1=3.0, c2=1.0, K=20.0)

    def build(Fc, _a0, _alpha, _l):
        F = ufl.variable(Fc)
        return [ufl.diff(mooney_rivlin(F, params), F), mooney_rivlin_stress(F, params)]

    ev = Evaluator(point, build)
    for _ in range(3):
        P, Pc = ev(F=np.eye(3) + 0.3 * RNG.standard_normal((3, 3)) * [1, 1, 1])
        np.testing.assert_allclose(P, Pc, rtol=1e-10, atol=1e-10)


def test_objectivity_and_transverse_isotropy(muscle_eval):
    """W(QF) = W(F), P(QF) = Q P(F); W(F R) = W(F) for rotations R about a0 only."""
    a = _unit([1.0, -0.5, 2.0])
    F = np.eye(3) + 0.15 * RNG.standard_normal((3, 3)) + 0.2 * np.outer(a, a)
    W, P, _, _ = muscle_eval(F=F, a0=a, alpha=0.7)
    for angle in (0.3, 1.7, 3.0):
        Q = _rotation(RNG.standard_normal(3), angle)
        Wq, Pq, _, _ = muscle_eval(F=Q @ F)
        assert Wq == pytest.approx(W, rel=1e-12)
        np.testing.assert_allclose(Pq, Q @ P, atol=1e-9 * np.abs(P).max())
        R = _rotation(a, angle)  # material symmetry: rotation about the fibre
        Wr, Pr, _, _ = muscle_eval(F=F @ R)
        assert Wr == pytest.approx(W, rel=1e-12)
        np.testing.assert_allclose(Pr, P @ R, atol=1e-9 * np.abs(P).max())
        R_off = _rotation(np.cross(a, [0.0, 0.0, 1.0]), angle)  # not a symmetry
        assert abs(muscle_eval(F=F @ R_off)[0] - W) > 1e-6 * abs(W)


def test_generic_transversely_isotropic_form(point):
    """psi_iso(F) + psi_fibre(a0.C a0) differentiates to the expected fibre stress 2 psi_f' F a0 x a0."""
    k = 5.0

    def build(Fc, a0, _alpha, _l):
        F = ufl.variable(Fc)
        psi = transversely_isotropic(F, a0, lambda G: 0.5 * ufl.inner(G, G), lambda I4: 0.5 * k * (I4 - 1) ** 2)
        return [ufl.diff(psi, F)]

    ev = Evaluator(point, build)
    a = _unit([0.2, 1.0, 0.1])
    F = np.eye(3) + 0.2 * RNG.standard_normal((3, 3))
    (P,) = ev(F=F, a0=a)
    I4 = a @ F.T @ F @ a
    np.testing.assert_allclose(P, F + 2 * k * (I4 - 1) * np.outer(F @ a, a), rtol=1e-12, atol=1e-12)


def test_tendon_stiffer_than_muscle(muscle_eval, point):
    tendon = MuscleParameters.tendon()

    def build(Fc, a0, _alpha, _l):
        F = ufl.variable(Fc)
        return [muscle(F, a0, 0.0, tendon), ufl.diff(muscle(F, a0, 0.0, tendon), F)]

    ev = Evaluator(point, build)
    a = np.array([0.0, 0.0, 1.0])
    for F in (np.diag([1 / math.sqrt(1.1), 1 / math.sqrt(1.1), 1.1]), np.eye(3) + 0.2 * np.outer([1, 0, 0], a)):
        Wt, Pt = ev(F=F, a0=a)
        Wm, Pm, _, _ = muscle_eval(F=F, a0=a, alpha=0.0)
        assert Wt > Wm > 0
        assert np.linalg.norm(Pt) > np.linalg.norm(Pm)


# -- homogeneous fibre-direction stretch of a unit cube --------------------------------------------
def _cube_matrix_energy(lam, s, p):
    """Smooth part of W(diag(lam, s, s)): Mooney-Rivlin + (K/2) ln^2 J, in numpy."""
    J = lam * s * s
    I1 = J ** (-2 / 3) * (lam**2 + 2 * s**2)
    I2 = J ** (-4 / 3) * (2 * lam**2 * s**2 + s**4)
    return p.c1 * (I1 - 3) + p.c2 * (I2 - 3) + 0.5 * p.K * math.log(J) ** 2


def _cube_gradient(lam, s, alpha, p):
    """(dW/dlam, dW/ds) for fibres along x: central differences of the smooth part plus
    the exact fibre part T_max (alpha f_act + f_pas)(l) dl, l = lam^(2/3) s^(-2/3) / lambda_ofl."""
    h = 1e-6
    dm_dlam = (_cube_matrix_energy(lam + h, s, p) - _cube_matrix_energy(lam - h, s, p)) / (2 * h)
    dm_ds = (_cube_matrix_energy(lam, s + h, p) - _cube_matrix_energy(lam, s - h, p)) / (2 * h)
    ell = (lam / s) ** (2 / 3) / p.lambda_ofl
    f = p.T_max * (alpha * float(f_act_ref(ell)) + float(f_pas_ref(ell, p.P1, p.P2, p.l_star)))
    return dm_dlam + f * (2 / 3) * ell / lam, dm_ds - f * (2 / 3) * ell / s


def _analytic_nominal_stress(lam, alpha, p):
    """Solve dW/ds = 0 (traction-free lateral faces) by bisection, return P_xx = dW/dlam and s."""
    lo, hi = 0.5, 1.5
    assert _cube_gradient(lam, lo, alpha, p)[1] < 0 < _cube_gradient(lam, hi, alpha, p)[1]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _cube_gradient(lam, mid, alpha, p)[1] < 0 else (lo, mid)
    s = 0.5 * (lo + hi)
    return _cube_gradient(lam, s, alpha, p)[0], s


def test_cube_fibre_stretch_nominal_stress():
    """Unit cube, fibres along x, rollers on x=0, y=0, z=0 and u_x = lam - 1 on x=1.

    The deformation is homogeneous, F = diag(lam, s, s), so P1 elements are exact;
    the reaction at x = 1 over the unit area is the nominal stress P_xx, to be
    compared with dW/dlam at the s that makes the lateral stress vanish.
    """
    p = MuscleParameters.muscle()
    mesh = dmesh.create_unit_cube(MPI.COMM_WORLD, 2, 2, 2, dmesh.CellType.tetrahedron)
    domain = hf.Domain.from_locators(
        mesh,
        {
            "x0": lambda x: np.isclose(x[0], 0),
            "x1": lambda x: np.isclose(x[0], 1),
            "y0": lambda x: np.isclose(x[1], 0),
            "z0": lambda x: np.isclose(x[2], 0),
        },
    )
    a0 = ufl.as_vector([1.0, 0.0, 0.0])
    act = Activation(mesh, 0.0)
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("z0", [0.0], components=[2]),
        hf.PrescribedDisplacement("x1", [0.1], components=[0]),
    ]  # u_x = 0.1 s
    problem = hf.HyperelasticProblem(domain, lambda F: muscle(F, a0, act.expr, p), bcs=bcs, updaters=[act])
    solver = hf.NewtonSolver(problem)
    reaction = ReactionForce(problem, "x1")
    for s_load, alpha in ((2.0, 0.5), (-2.0, 1.0), (3.0, 0.0)):  # lam = 1.2, 0.8, 1.3
        act.set(alpha)
        for frac in (0.5, 1.0):
            problem.set_time(frac * s_load)
            assert solver.solve().converged
        lam = 1.0 + 0.1 * s_load
        expected, s_lat = _analytic_nominal_stress(lam, alpha, p)
        assert reaction()[0] == pytest.approx(expected, rel=1e-7)
        # the lateral stretch of the FE solution is the analytic one
        x = problem.u.function_space.tabulate_dof_coordinates()
        corner = np.isclose(x[:, 1], 1.0)
        uy = problem.u.x.array.reshape(-1, 3)[corner, 1]
        if uy.size:
            np.testing.assert_allclose(uy, s_lat - 1.0, atol=1e-7)
        problem.set_time(0.0)
        problem.u.x.array[:] = 0.0
