"""Kinematic helpers against numpy.

A displacement ``u = A X + b`` is interpolated exactly into a P1 space on a
one-cell mesh (``MPI.COMM_SELF``), so ``grad u = A`` and every kinematic
quantity is a known matrix function of ``F = I + A``.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem
from dolfinx import mesh as dmesh

from hyperfem import kinematics as kin


# Each rank compiles on MPI.COMM_SELF into the shared cache; a rank that finds the
# module being compiled by another waits for it (10 s by default: too short on a busy machine).
JIT_OPTIONS = {"timeout": 300}

class _Kinematics:
    def __init__(self, dim: int):
        if dim == 2:
            self.mesh = dmesh.create_unit_square(MPI.COMM_SELF, 1, 1)
        else:
            self.mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
        self.dim = dim
        V = fem.functionspace(self.mesh, ("Lagrange", 1, (dim,)))
        self.u = fem.Function(V)
        F = kin.deformation_gradient(self.u)
        F3 = kin.plane_strain_3d(F)
        C3 = kin.right_cauchy_green(F3)
        I1, I2, I3 = kin.invariants(C3)
        Ib1, Ib2, Jb = kin.isochoric_invariants(F)
        tensors = [F, kin.right_cauchy_green(F), kin.green_lagrange(F), kin.small_strain(F), F3]
        flat = [T[i, j] for T in tensors for i in range(T.ufl_shape[0]) for j in range(T.ufl_shape[1])]
        scalars = [kin.jacobian(F), I1, I2, I3, Ib1, Ib2, Jb]
        self.expr = fem.Expression(
            ufl.as_vector(flat + scalars), np.full((1, dim), 0.2), jit_options=JIT_OPTIONS
        )
        self.cells = np.array([0], dtype=np.int32)

    def __call__(self, A: np.ndarray, b: np.ndarray) -> dict:
        d = self.dim
        self.u.interpolate(lambda x: A @ x[:d] + b[:, None])
        v = self.expr.eval(self.mesh, self.cells).reshape(-1)
        out, k = {}, 0
        for name, n in [("F", d), ("C", d), ("E", d), ("eps", d), ("F3", 3)]:
            out[name] = v[k : k + n * n].reshape(n, n)
            k += n * n
        for name in ["J", "I1", "I2", "I3", "Ibar1", "Ibar2", "Jiso"]:
            out[name] = v[k]
            k += 1
        return out


@cache
def kinematics(dim: int) -> _Kinematics:
    return _Kinematics(dim)


def _numpy_reference(F: np.ndarray) -> dict:
    d = F.shape[0]
    F3 = np.eye(3)
    F3[:d, :d] = F
    C3 = F3.T @ F3
    lam = np.linalg.eigvalsh(C3)  # principal stretches squared
    J = np.linalg.det(F)
    return {
        "F": F,
        "C": F.T @ F,
        "E": 0.5 * (F.T @ F - np.eye(d)),
        "eps": 0.5 * (F + F.T) - np.eye(d),
        "F3": F3,
        "J": J,
        # invariants from the eigenvalues: an independent formula
        "I1": lam.sum(),
        "I2": lam[0] * lam[1] + lam[1] * lam[2] + lam[0] * lam[2],
        "I3": lam.prod(),
        "Ibar1": J ** (-2 / 3) * lam.sum(),
        "Ibar2": J ** (-4 / 3) * (lam[0] * lam[1] + lam[1] * lam[2] + lam[0] * lam[2]),
        "Jiso": J,
    }


@pytest.mark.parametrize("dim", [2, 3])
def test_kinematics_against_numpy(dim):
    rng = np.random.default_rng(2024 + dim)
    ev = kinematics(dim)
    for _ in range(4):
        while True:
            A = 0.4 * rng.standard_normal((dim, dim))
            if np.linalg.det(np.eye(dim) + A) > 0.2:
                break
        b = rng.standard_normal(dim)
        got = ev(A, b)
        ref = _numpy_reference(np.eye(dim) + A)
        for key, value in ref.items():
            np.testing.assert_allclose(got[key], value, rtol=1e-12, atol=1e-12, err_msg=key)


@pytest.mark.parametrize("dim", [2, 3])
def test_isochoric_invariants_are_volume_independent(dim):
    """Ibar1, Ibar2 are unchanged by a pure dilatation (3D) and equal 3 at F = I."""
    ev = kinematics(dim)
    rng = np.random.default_rng(3)
    A = 0.3 * rng.standard_normal((dim, dim))
    F = np.eye(dim) + A
    if dim == 3:
        a = ev(A, np.zeros(dim))
        b = ev(1.37 * F - np.eye(dim), np.zeros(dim))
        assert b["Ibar1"] == pytest.approx(a["Ibar1"], rel=1e-12)
        assert b["Ibar2"] == pytest.approx(a["Ibar2"], rel=1e-12)
        assert b["Jiso"] == pytest.approx(1.37**3 * a["Jiso"], rel=1e-12)
    ident = ev(np.zeros((dim, dim)), np.zeros(dim))
    assert ident["Ibar1"] == pytest.approx(3.0, rel=1e-14)
    assert ident["Ibar2"] == pytest.approx(3.0, rel=1e-14)
    assert ident["I3"] == pytest.approx(1.0, rel=1e-14)


def test_plane_strain_embedding_of_3d_tensor_is_identity():
    """plane_strain_3d returns a 3x3 tensor unchanged (same object)."""
    mesh = dmesh.create_unit_cube(MPI.COMM_SELF, 1, 1, 1)
    F = fem.Constant(mesh, np.eye(3))
    assert kin.plane_strain_3d(F) is F
    mesh2 = dmesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    F2 = fem.Constant(mesh2, np.eye(2))
    assert kin.plane_strain_3d(F2).ufl_shape == (3, 3)


def test_plane_strain_invariants_example():
    """Hand-computed plane strain case: F = diag(2, 1/2) embeds to diag(2, 1/2, 1)."""
    got = kinematics(2)(np.diag([1.0, -0.5]), np.zeros(2))
    assert got["J"] == pytest.approx(1.0, rel=1e-14)
    assert got["I1"] == pytest.approx(4 + 0.25 + 1, rel=1e-14)
    assert got["I2"] == pytest.approx(4 * 0.25 + 0.25 * 1 + 4 * 1, rel=1e-14)
    assert got["I3"] == pytest.approx(1.0, rel=1e-14)
    assert got["Ibar1"] == pytest.approx(5.25, rel=1e-14)
