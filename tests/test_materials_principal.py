r"""Principal-stretch energies: exact derivatives where stretches coincide, closed forms, parameters.

Point checks evaluate UFL expressions with :class:`dolfinx.fem.Expression` on a
one-cell mesh (``MPI.COMM_SELF``, every rank on its own) with :math:`F` a
:class:`dolfinx.fem.Constant`, as ``tests/test_materials.py`` does:

* the spectral machinery against exact invariant expressions: Ogden sums with
  the even exponents (2, 4, -2), whose stretch sums are :math:`\operatorname{tr}\bar C`,
  :math:`\operatorname{tr}\bar C^2`, :math:`\operatorname{tr}\bar C^{-1}`, through
  ``eigenvalue_power_sum`` (the path of Ogden's law), and Saint Venant–Kirchhoff
  in stretches through ``eigenvalue_sum`` against the invariant law: energy,
  stress and tangent at :math:`F = I`, exact uniaxial and equibiaxial states,
  three distinct stretches, rotated copies and states next to the branch
  thresholds;
* Ogden (exponents 1.3, 5, -2.5) and Hencky against NumPy's spectral stresses
  :math:`P = F\sum_i \frac{\tau_i}{c_i} n_i\otimes n_i`, and objectivity; the
  series of ``eigenvalue_sum`` (by ``ufl.diff``) against those of ``eigenvalue_power_sum``;
* volume preservation :math:`k(\prod_i\lambda_i - 1)^2` against NumPy's singular values.

Taylor tests of :math:`\Pi \to R \to K` on a small box in *exactly* homogeneous
degenerate states (and distinct, and rotated) for Ogden and Hencky, serially and
on several ranks, with no NaN in the assembled tangent. The homogeneous uniaxial,
equibiaxial and pure-shear tests of the three-field formulation are compared with
the compressible closed form (the lateral stretch solved from :math:`\tau = 0`),
which tends to Ogden's incompressible formulas as :math:`K/\mu` grows.

The forms here are compiled with ``-O0`` (``JIT``): the spectral tangents are large
C functions (see ``benchmarks/materials_principal.py``), and these meshes are tiny.
"""

from __future__ import annotations

import math
import warnings
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
from hyperfem.kinematics import right_cauchy_green
from hyperfem.materials import LameParameters, saint_venant_kirchhoff
from hyperfem.materials.mooney_rivlin import mooney_rivlin_isochoric
from hyperfem.materials.ogden import (
    OgdenParameters,
    ogden,
    ogden_equibiaxial_stress,
    ogden_isochoric,
    ogden_pure_shear_stress,
    ogden_uniaxial_stress,
)
from hyperfem.materials.principal_stretches import (
    eigenvalue_power_sum,
    eigenvalue_sum,
    hencky,
    invariant_power_sum,
    saint_venant_kirchhoff_principal,
    spectral_invariants,
    volume_preservation,
)
from hyperfem.problem import MixedHyperelasticProblem, SplitEnergy

JIT = {"cffi_extra_compile_args": ["-O0", "-g0"], "timeout": 600}
LAME = LameParameters(mu=3.7, lmbda=11.3)
OGDEN = OgdenParameters(mu=(0.63, 0.0012, -0.01), alpha=(1.3, 5.0, -2.5), K=4.0)
EVEN = ((1.0, 2.0), (0.3, 4.0), (-0.2, -2.0))  # (mu_p, alpha_p) with exact invariant sums
CELLS = np.array([0], dtype=np.int32)
IDX = [(i, j) for i in range(3) for j in range(3)]


def _diag(*stretches: float) -> np.ndarray:
    return np.diag(np.asarray(stretches, dtype=float))


def _rotation(rng: np.random.Generator) -> np.ndarray:
    Q, R = np.linalg.qr(rng.standard_normal((3, 3)))
    Q = Q @ np.diag(np.sign(np.diag(R)))
    return Q if np.linalg.det(Q) > 0 else Q @ np.diag([-1.0, 1.0, 1.0])


def _states() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(5)
    Q1, Q2, Q3, Q4 = (_rotation(rng) for _ in range(4))
    s = 1.0 / math.sqrt(2.0)
    return {
        "identity": np.eye(3),
        "dilatation": 1.2 * np.eye(3),
        "uniaxial": _diag(2.0, s, s),
        "uniaxial_5": _diag(5.0, 5.0**-0.5, 5.0**-0.5),
        "equibiaxial": _diag(1.5, 1.5, 1.0 / 2.25),
        "distinct": _diag(1.3, 0.8, 1.1),
        "rotated_identity": Q1 @ Q2.T,
        "rotated_uniaxial": Q1 @ _diag(2.0, s, s) @ Q2.T,
        "rotated_equibiaxial": Q3 @ _diag(1.2, 1.2, 0.7) @ Q4.T,
        "near_identity": Q3 @ _diag(1.0 + 4e-4, 1.0 - 3e-4, 1.0 - 1e-4) @ Q1.T,
        "near_double": Q2 @ _diag(1.6, 0.8, 0.8 * (1.0 + 6e-4)) @ Q4.T,
    }


STATES = _states()


class _Point:
    """Values of a list of scalar UFL expressions of F (a Constant) at one point."""

    def __init__(self, build):
        self.mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
        self.Fc = fem.Constant(self.mesh, np.eye(3))
        entries = build(ufl.variable(self.Fc))
        self.expr = fem.Expression(ufl.as_vector(entries), np.full((1, 3), 0.25), jit_options=JIT)

    def __call__(self, F: np.ndarray) -> np.ndarray:
        self.Fc.value[:] = F
        return self.expr.eval(self.mesh, CELLS).reshape(-1)


def _psi_P_A(psi, F) -> list:
    P = ufl.diff(psi, F)
    A = ufl.diff(P, F)
    return [psi] + [P[i, j] for i, j in IDX] + [A[i, j, k, m] for i, j in IDX for k, m in IDX]


@cache
def exactness() -> _Point:
    """[psi, P, A] of: the even Ogden sum (spectral), its invariant form, SVK in stretches, SVK."""

    def build(F):
        J = ufl.det(F)
        Cb = J ** (-2.0 / 3.0) * right_cauchy_green(F)
        inv = spectral_invariants(right_cauchy_green(F)).scaled(J ** (-2.0 / 3.0))
        sums = {2.0: ufl.tr(Cb), 4.0: ufl.tr(Cb * Cb), -2.0: ufl.tr(ufl.inv(Cb))}
        spectral = eigenvalue_power_sum(inv, [m / a for m, a in EVEN], [a / 2 for _, a in EVEN])
        exact = sum(m / a * (sums[a] - 3.0) for m, a in EVEN)
        out = []
        for psi in (spectral, exact, saint_venant_kirchhoff_principal(F, LAME), saint_venant_kirchhoff(F, LAME)):
            out += _psi_P_A(psi, F)
        return out

    return _Point(build)


@pytest.mark.parametrize("state", list(STATES))
def test_spectral_sums_are_exact_to_second_derivatives(state):
    """Energy, stress and tangent equal the invariant forms to round-off, coincident stretches included."""
    v = exactness()(STATES[state]).reshape(4, 91)
    assert np.all(np.isfinite(v))
    for spectral, exact in ((v[0], v[1]), (v[2], v[3])):
        modulus = np.max(np.abs(exact[10:]))
        assert abs(spectral[0] - exact[0]) <= 1e-13 * max(1.0, abs(exact[0]))
        np.testing.assert_allclose(spectral[1:10], exact[1:10], rtol=0, atol=1e-13 * modulus)
        np.testing.assert_allclose(spectral[10:], exact[10:], rtol=0, atol=1e-11 * modulus)


def test_spectral_sums_near_the_branch_thresholds():
    """Random states around every switch (near C = sI, near a double root): tangent error < 1e-11."""
    rng = np.random.default_rng(11)
    point = exactness()
    worst = 0.0
    for spread in (2e-4, 6e-4, 1e-3, 1.5e-3):  # about the near-identity switch (rho/m = 1e-3)
        for _ in range(4):
            v = rng.standard_normal(3)
            v -= v.mean()
            F = _rotation(rng) @ np.diag(np.exp(spread * v / np.linalg.norm(v))) @ _rotation(rng).T
            out = point(F).reshape(4, 91)
            worst = max(worst, np.max(np.abs(out[0, 10:] - out[1, 10:])) / np.max(np.abs(out[1, 10:])))
    for gap in (3e-4, 5e-4, 1e-3, 3e-2):  # about the pair-series switch and the Cardano/Newton one
        for _ in range(3):
            F = _rotation(rng) @ _diag(1.8, 0.7, 0.7 * (1.0 + gap)) @ _rotation(rng).T
            out = point(F).reshape(4, 91)
            worst = max(worst, np.max(np.abs(out[0, 10:] - out[1, 10:])) / np.max(np.abs(out[1, 10:])))
    assert worst < 1e-11, worst


# --------------------------------------------------------------------------
# Closed-form stresses (NumPy), objectivity, volume preservation
# --------------------------------------------------------------------------
def _spectral_stress(F: np.ndarray, tau) -> np.ndarray:
    """P = F sum_i tau_i / c_i n_i n_i^T, tau(c, J) the principal Kirchhoff stresses (any basis of an eigenspace)."""
    c, n = np.linalg.eigh(F.T @ F)
    t = tau(c, np.linalg.det(F))
    return F @ (n * (t / c)) @ n.T


def _ogden_tau(c: np.ndarray, J: float, params: OgdenParameters = OGDEN) -> np.ndarray:
    cb = c * J ** (-2.0 / 3.0)
    dev = sum(m * (cb ** (a / 2) - np.mean(cb ** (a / 2))) for m, a in zip(params.mu, params.alpha, strict=True))
    return dev + params.K * math.log(J)


def _ogden_psi(F: np.ndarray) -> float:
    J = np.linalg.det(F)
    cb = np.linalg.eigvalsh(F.T @ F) * J ** (-2.0 / 3.0)
    return (
        sum(m / a * (np.sum(cb ** (a / 2)) - 3.0) for m, a in zip(OGDEN.mu, OGDEN.alpha, strict=True))
        + 0.5 * OGDEN.K * math.log(J) ** 2
    )


def _hencky_tau(c: np.ndarray, J: float) -> np.ndarray:
    return LAME.mu * np.log(c) + LAME.lmbda * math.log(J)


def _hencky_psi(F: np.ndarray) -> float:
    c = np.linalg.eigvalsh(F.T @ F)
    return 0.25 * LAME.mu * np.sum(np.log(c) ** 2) + 0.5 * LAME.lmbda * math.log(np.linalg.det(F)) ** 2


@cache
def laws() -> _Point:
    """[psi, P] of Ogden, Hencky, volume preservation (k = 2), and of ``eigenvalue_sum`` minus
    ``eigenvalue_power_sum`` for one f (series by ``ufl.diff`` against binomials)."""

    def build(F):
        J = ufl.det(F)
        inv = spectral_invariants(right_cauchy_green(F)).scaled(J ** (-2.0 / 3.0))
        generic = eigenvalue_sum(inv, lambda c: 0.7 * (c**0.65 - 1.0) - 0.1 * (c**-1.25 - 1.0))
        power = eigenvalue_power_sum(inv, [0.7, -0.1], [0.65, -1.25])
        out = []
        for psi in (ogden(F, OGDEN), hencky(F, LAME), volume_preservation(F, 2.0), generic - power):
            P = ufl.diff(psi, F)
            out += [psi] + [P[i, j] for i, j in IDX]
        return out

    return _Point(build)


@pytest.mark.parametrize("state", list(STATES))
def test_stress_matches_spectral_closed_form(state):
    F = STATES[state]
    v = laws()(F).reshape(4, 10)
    assert np.all(np.isfinite(v))
    references = ((_ogden_psi, _ogden_tau), (_hencky_psi, _hencky_tau))
    for (psi_np, tau), row in zip(references, v[:2], strict=True):
        P_np = _spectral_stress(F, tau)
        assert row[0] == pytest.approx(psi_np(F), rel=1e-12, abs=1e-14)
        np.testing.assert_allclose(row[1:].reshape(3, 3), P_np, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(P_np))))
    # volume preservation: k (prod of the stretches - 1)^2, P = 2 k (J - 1) cof F
    J = np.linalg.det(F)
    assert v[2, 0] == pytest.approx(
        2.0 * (np.prod(np.linalg.svd(F, compute_uv=False)) - 1.0) ** 2, rel=1e-12, abs=1e-14
    )
    np.testing.assert_allclose(v[2, 1:].reshape(3, 3), 4.0 * (J - 1.0) * J * np.linalg.inv(F).T, rtol=0, atol=1e-13)
    # the series of eigenvalue_sum (ufl.diff) and eigenvalue_power_sum (binomials) agree
    assert np.max(np.abs(v[3])) < 1e-13


def test_objectivity():
    """psi(QF) = psi(F) and P(QF) = Q P(F) at coincident and distinct stretches."""
    rng = np.random.default_rng(3)
    point = laws()
    for state in ("identity", "uniaxial", "equibiaxial", "distinct", "near_double"):
        F = STATES[state]
        Q = _rotation(rng)
        a, b = point(F).reshape(4, 10), point(Q @ F).reshape(4, 10)
        for k in (0, 1):
            assert b[k, 0] == pytest.approx(a[k, 0], rel=1e-12, abs=1e-14)
            np.testing.assert_allclose(
                b[k, 1:].reshape(3, 3), Q @ a[k, 1:].reshape(3, 3), rtol=0, atol=1e-12 * max(1.0, np.abs(a[k]).max())
            )


def test_plane_strain_is_the_embedded_law():
    """A 2x2 F is evaluated as diag(F, 1): energy and in-plane stress of the 3D law."""
    mesh = dmesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    Fc = fem.Constant(mesh, np.eye(2))
    F = ufl.variable(Fc)
    entries = []
    for psi in (ogden(F, OGDEN), hencky(F, LAME)):
        P = ufl.diff(psi, F)
        entries += [psi] + [P[i, j] for i in range(2) for j in range(2)]
    expr = fem.Expression(ufl.as_vector(entries), np.full((1, 2), 0.25), jit_options=JIT)
    for F2 in (np.eye(2), np.diag([1.5, 0.9]), np.array([[1.2, 0.3], [-0.1, 0.9]]), np.diag([1.0, 1.3])):
        Fc.value[:] = F2
        v = expr.eval(mesh, CELLS).reshape(2, 5)
        F3 = np.eye(3)
        F3[:2, :2] = F2
        w = laws()(F3).reshape(4, 10)
        for k in (0, 1):
            assert v[k, 0] == pytest.approx(w[k, 0], rel=1e-13, abs=1e-15)
            np.testing.assert_allclose(v[k, 1:], w[k, 1:].reshape(3, 3)[:2, :2].ravel(), rtol=0, atol=1e-13)


def test_invariant_power_sums():
    rng = np.random.default_rng(1)
    C = rng.standard_normal((3, 3))
    C = C @ C.T + np.eye(3)
    c = np.linalg.eigvalsh(C)
    I1, I2, I3 = np.sum(c), 0.5 * (np.sum(c) ** 2 - np.sum(c * c)), np.prod(c)
    for k in (-3, -2, -1, 1, 2, 3, 4, 5):
        assert invariant_power_sum(I1, I2, I3, k) == pytest.approx(np.sum(c**k), rel=1e-12)
    with pytest.raises(ValueError):
        invariant_power_sum(I1, I2, I3, 0)


# --------------------------------------------------------------------------
# Taylor tests on a mesh in homogeneous states
# --------------------------------------------------------------------------
STEPS = 4e-3 / 2.0 ** np.arange(5)


class _Taylor:
    """Pi, R, K of w0 * ogden + w1 * hencky on a small box, at u = (F0 - I) X + h du (no Dirichlet conditions).

    PETSc objects are created and destroyed explicitly, as in ``tests/test_taylor.py``.
    """

    def __init__(self):
        mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.array([1.0, 0.6, 0.5])], [2, 1, 1])
        self.comm = mesh.comm
        self.V = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
        self.u = fem.Function(self.V)
        self.weights = fem.Constant(mesh, np.array([1.0, 0.0]))
        F = ufl.Identity(3) + ufl.grad(self.u)
        psi = self.weights[0] * ogden(F, OGDEN) + self.weights[1] * hencky(F, LAME)
        Pi = psi * ufl.dx(metadata={"quadrature_degree": 1})
        R = ufl.derivative(Pi, self.u, ufl.TestFunction(self.V))
        K = ufl.derivative(R, self.u, ufl.TrialFunction(self.V))
        self.forms = [fem.form(f, jit_options=JIT) for f in (Pi, R, K)]
        rng = np.random.default_rng(23)  # same numbers on every rank
        coeffs = rng.standard_normal((3, 3))
        self.du = fem.Function(self.V)
        self.du.interpolate(lambda x: coeffs @ np.array([np.sin(2 * x[0] + x[1]), x[1] * x[2], np.cos(x[0] - x[2])]))
        self.u0 = np.zeros_like(self.u.x.array)

    def at(self, F0: np.ndarray, law: int) -> None:
        self.weights.value[:] = [1.0, 0.0] if law == 0 else [0.0, 1.0]
        self.u.interpolate(lambda x: (F0 - np.eye(3)) @ x)
        self.u0 = self.u.x.array.copy()

    def _set(self, h: float) -> None:
        self.u.x.array[:] = self.u0 + h * self.du.x.array
        self.u.x.scatter_forward()

    def Pi(self, h: float) -> float:
        self._set(h)
        return self.comm.allreduce(fem.assemble_scalar(self.forms[0]), op=MPI.SUM)

    def R(self, h: float) -> PETSc.Vec:
        self._set(h)
        b = fpetsc.assemble_vector(self.forms[1])
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return b

    def K_du(self) -> tuple[PETSc.Vec, float]:
        """K(u0) du and the Frobenius norm of K(u0) (NaN if any entry is)."""
        self._set(0.0)
        A = fpetsc.assemble_matrix(self.forms[2])
        A.assemble()
        norm = A.norm()
        x, y = A.createVecs()
        x.array[:] = self.du.x.array[: x.getLocalSize()]
        A.mult(x, y)
        x.destroy()
        A.destroy()
        return y, norm

    def dot_du(self, b: PETSc.Vec) -> float:
        n = b.getLocalSize()
        return self.comm.allreduce(float(np.dot(b.array_r, self.du.x.array[:n])), op=MPI.SUM)


@cache
def taylor() -> _Taylor:
    return _Taylor()


def _rates(errors: np.ndarray) -> np.ndarray:
    return np.log2(errors[:-1] / errors[1:])


TAYLOR_STATES = ["identity", "uniaxial", "equibiaxial", "distinct", "rotated_uniaxial", "rotated_identity"]


@pytest.mark.parametrize("law", [0, 1], ids=["ogden", "hencky"])
@pytest.mark.parametrize("state", TAYLOR_STATES)
def test_taylor_energy_residual_tangent(state, law):
    """Pi -> R and R -> K remainders decay like h^2 at exact degenerate states; no NaN in R or K."""
    t = taylor()
    t.at(STATES[state], law)
    Pi0 = t.Pi(0.0)
    R0 = t.R(0.0)
    dPi = t.dot_du(R0)
    Kdu, K_norm = t.K_du()
    assert np.isfinite(Pi0) and np.isfinite(R0.norm()) and np.isfinite(K_norm) and K_norm > 1e-3
    e0, e1 = [], []
    for h in STEPS:
        e0.append(abs(t.Pi(h) - Pi0 - h * dPi))
        Rh = t.R(h)
        Rh.axpy(-1.0, R0)
        Rh.axpy(-h, Kdu)
        e1.append(Rh.norm())
        Rh.destroy()
    scale = Kdu.norm()
    for v in (R0, Kdu):
        v.destroy()
    e0, e1 = np.array(e0), np.array(e1)
    assert np.all(np.abs(_rates(e0) - 2.0) < 0.1), (e0, _rates(e0))
    assert np.all(np.abs(_rates(e1) - 2.0) < 0.1), (e1, _rates(e1))
    assert e1[-1] < 1e-3 * STEPS[-1] * scale


# --------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------
def test_conventions_give_the_same_law():
    """Ogden's mu_p, FEBio's c_p = mu_p alpha_p and Abaqus's mu_p alpha_p / 2 are one material."""
    mu, alpha = (0.63, 0.0012, -0.01), (1.3, 5.0, -2.0)
    ref = OgdenParameters(mu=mu, alpha=alpha, K=1e3)
    febio = OgdenParameters.from_convention(
        [m * a for m, a in zip(mu, alpha, strict=True)], alpha, K=1e3, convention="febio"
    )
    abaqus = OgdenParameters.from_convention(
        [m * a / 2 for m, a in zip(mu, alpha, strict=True)], alpha, K=1e3, convention="abaqus"
    )
    same = OgdenParameters.from_convention(mu, alpha, K=1e3, convention="ogden")
    for p in (febio, abaqus, same):
        np.testing.assert_allclose(p.mu, ref.mu, rtol=1e-15)
        assert p.shear_modulus == pytest.approx(ref.shear_modulus, rel=1e-15)
    assert ref.shear_modulus == pytest.approx(0.5 * (0.63 * 1.3 + 0.0012 * 5.0 + 0.01 * 2.0))
    assert abaqus.shear_modulus == pytest.approx(sum(m * a / 2 for m, a in zip(mu, alpha, strict=True)))
    # the same energy: the closed-form uniaxial stress of each
    for p in (febio, abaqus):
        np.testing.assert_allclose(
            ogden_uniaxial_stress([1.5, 3.0], p.mu, p.alpha), ogden_uniaxial_stress([1.5, 3.0], mu, alpha), rtol=1e-14
        )


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(mu=(1.0, 2.0), alpha=(2.0,), K=1.0), "equal lengths"),
        (dict(mu=(1.0,), alpha=(0.0,), K=1.0), r"alpha\[0\] must be nonzero"),
        (dict(mu=(1.0, 0.5), alpha=(2.0, -2.0), K=1.0), "term 1 needs mu\\*alpha > 0"),
        (dict(mu=(float("nan"),), alpha=(2.0,), K=1.0), r"mu\[0\] must be a finite number"),
        (dict(mu=(1.0,), alpha=(float("inf"),), K=1.0), r"alpha\[0\] must be a finite number"),
        (dict(mu=(), alpha=(), K=1.0), "mu is empty"),
        (dict(mu=1.0, alpha=(2.0,), K=1.0), "mu must be a sequence"),
        (dict(mu=(1.0,), alpha=(2.0,), K=0.0), "K must be a finite number > 0"),
        (dict(mu=(1.0,), alpha=(2.0,), K=1.0, volumetric="cubic"), "unknown volumetric law"),
    ],
)
def test_parameter_validation(kwargs, match):
    with pytest.raises(ParameterError, match=match) as info:
        OgdenParameters(**kwargs)
    assert "\n" not in str(info.value)


def test_unknown_convention():
    with pytest.raises(ParameterError, match="unknown convention 'ansys'"):
        OgdenParameters.from_convention((1.0,), (2.0,), K=1.0, convention="ansys")
    with pytest.raises(ParameterError, match="equal lengths"):
        OgdenParameters.from_convention((1.0, 2.0), (2.0,), K=1.0, convention="febio")


def test_even_exponents_are_mooney_rivlin():
    """alpha = (2, -2) is Mooney-Rivlin with c1 = mu_1 / 2, c2 = -mu_2 / 2 (the invariant path, no eigenvalues)."""
    point = _Point(lambda F: [ogden_isochoric(F, (1.4, -0.6), (2.0, -2.0)) - mooney_rivlin_isochoric(F, 0.7, 0.3)])
    for F in (STATES["distinct"], STATES["rotated_uniaxial"], np.eye(3)):
        assert abs(point(F)[0]) < 1e-13


# --------------------------------------------------------------------------
# Homogeneous tests of the three-field formulation, up to stretch 5
# --------------------------------------------------------------------------
TRELOAR = OgdenParameters(mu=(0.63, 0.0012, -0.01), alpha=(1.3, 5.0, -2.0), K=422.5)  # Ogden 1972; K/mu0 = 1000
CASES = {  # fixed stretches (None: the free one), and the loaded faces
    "uniaxial": (lambda lam: (lam, None, None), ogden_uniaxial_stress),
    "equibiaxial": (lambda lam: (lam, lam, None), ogden_equibiaxial_stress),
    "pure_shear": (lambda lam: (lam, 1.0, None), ogden_pure_shear_stress),
}


def compressible_nominal_stress(case: str, lam: float, params: OgdenParameters) -> float:
    """P_11 of the homogeneous state with the free stretches solved from tau = 0 (log volumetric law).

    tau_i = sum_p mu_p (lbar_i^alpha_p - mean_j lbar_j^alpha_p) + K ln J, lbar = J^(-1/3) lambda; the free
    stretches are equal, and tau_free increases with them (bisection on a bracket).
    """
    fixed = CASES[case][0](lam)

    def tau(free: float) -> np.ndarray:
        stretches = np.array([free if s is None else s for s in fixed])
        c = stretches**2
        return _ogden_tau(c, float(np.prod(stretches)), params)

    k = fixed.index(None)
    lo, hi = 1e-3, 10.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if tau(mid)[k] < 0 else (lo, mid)
    return float(tau(0.5 * (lo + hi))[0] / lam)


@pytest.mark.parametrize("case", list(CASES))
def test_compressible_closed_form_tends_to_incompressible(case):
    """The reference of the FE test tends to Ogden's incompressible formulas: the gap shrinks like mu0 / K."""
    incompressible = CASES[case][1]
    for lam in (1.5, 3.0, 5.0):
        exact = float(incompressible(lam, TRELOAR.mu, TRELOAR.alpha))
        gaps = []
        for ratio in (1e3, 1e5, 1e7):
            params = OgdenParameters(TRELOAR.mu, TRELOAR.alpha, K=ratio * TRELOAR.shear_modulus)
            gaps.append(abs(compressible_nominal_stress(case, lam, params) - exact) / abs(exact))
        # (at K/mu0 = 1e7 the bisection's round-off, K * 1e-16, is near the gap itself)
        assert gaps[1] / gaps[0] == pytest.approx(1e-2, rel=0.2) and gaps[2] < 1e-5, gaps


def _cube() -> hf.Domain:
    mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), np.ones(3)], [1, 1, 1], dmesh.CellType.tetrahedron)
    return hf.Domain.from_locators(
        mesh,
        {
            "x0": lambda x: np.isclose(x[0], 0.0),
            "x1": lambda x: np.isclose(x[0], 1.0),
            "y0": lambda x: np.isclose(x[1], 0.0),
            "y1": lambda x: np.isclose(x[1], 1.0),
            "z0": lambda x: np.isclose(x[2], 0.0),
        },
    )


def _bcs(case: str, lam: float) -> list[hf.PrescribedDisplacement]:
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("z0", [0.0], components=[2]),
        hf.PrescribedDisplacement("x1", [lam - 1.0], components=[0]),
    ]
    if case == "equibiaxial":
        bcs.append(hf.PrescribedDisplacement("y1", [lam - 1.0], components=[1]))
    elif case == "pure_shear":
        bcs.append(hf.PrescribedDisplacement("y1", [0.0], components=[1]))
    return bcs


def test_mixed_homogeneous_up_to_stretch_5():
    """Uniaxial, equibiaxial and pure shear of the unit cube (1 box, P2/P1/P1) to stretch 5, in 8 steps.

    K/mu0 = 1e8. The nominal stress P_11 (the x1 reaction over the unit area) matches, at every step, the
    compressible closed form (the deformation is homogeneous, so exactly representable; measured 3e-8, K
    times round-off on both sides; 3e-10 at K/mu0 = 1e3) and Ogden's incompressible formulas (measured
    2.7e-7, equibiaxial stretch 5: the compressible gap mu0/K; 2.5e-2 at K/mu0 = 1e3), both to 1e-6.
    The residual's floor, K times round-off (~1e-9), lies above snes_atol: the solves end at it and say so
    (CONVERGED_ROUNDOFF, the floor of theta in hyperfem.solver.roundoff; without it they ran to snes_max_it).
    """
    lam_max = 5.0
    params = OgdenParameters(TRELOAR.mu, TRELOAR.alpha, K=1e8 * TRELOAR.shear_modulus)
    material = SplitEnergy(lambda F: ogden_isochoric(F, params.mu, params.alpha), params.K)
    for case, (_, incompressible) in CASES.items():
        domain = _cube()
        problem = MixedHyperelasticProblem(domain, material, bcs=_bcs(case, lam_max))
        chi = fem.Function(problem.W)
        chi.x.array[fem.locate_dofs_topological(problem.W.sub(0).sub(0), 2, domain.facets("x1"))] = 1.0
        reaction = fem.form(ufl.derivative(problem.energy_internal, problem.u, chi), jit_options=JIT)
        solver = hf.NewtonSolver(problem, jit_options=JIT)
        rows = []

        def check(record, case=case, reaction=reaction, rows=rows, domain=domain):
            lam = 1.0 + (lam_max - 1.0) * record.time
            rows.append((lam, domain.comm.allreduce(fem.assemble_scalar(reaction), op=MPI.SUM)))

        stepping = hf.LoadStepping(initial_increment=0.125, max_increment=0.125)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", hf.RoundoffWarning)  # the tolerance is below the floor: it says so
            records = hf.solve_quasistatic(solver, stepping=stepping, on_step=check)
        assert len(rows) == 8 and rows[-1][0] == pytest.approx(lam_max)
        reasons = [r.solve_records[-1].reason_name for r in records]
        assert "CONVERGED_ROUNDOFF" in reasons and not any(r.failed for r in records), (case, reasons)
        for lam, P11 in rows:
            assert P11 == pytest.approx(compressible_nominal_stress(case, lam, params), rel=1e-6), (case, lam)
            assert P11 == pytest.approx(float(incompressible(lam, params.mu, params.alpha)), rel=1e-6), (case, lam)
