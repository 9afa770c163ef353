"""Taylor remainders of an energy density on a small P1 mesh: the shared check of the material tests.

At a stretched random state :math:`u_0` and a random direction :math:`\\delta u`,

* energy → residual: :math:`|\\Pi(u_0 + h\\delta u) - \\Pi(u_0) - h\\,R(u_0)\\cdot\\delta u| = O(h^2)`;
* residual → tangent: :math:`\\|R(u_0 + h\\delta u) - R(u_0) - h\\,K(u_0)\\delta u\\| = O(h^2)`,

with :math:`R` and :math:`K` from ``ufl.derivative``. The tangent is applied
to :math:`\\delta u` as the vector form :math:`K(u)\\delta u`: a matrix's
column layout in parallel (its sparsity pattern's ghosts) is not the function
space's. The fields are smooth and the same on every partition, so the rates
are the same on 1 and 2 ranks.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import ufl
from mpi4py import MPI

from dolfinx import fem, la
from dolfinx import mesh as dmesh

from hyperfem.kinematics import deformation_gradient

JIT_OPTIONS = {"timeout": 300}  # a rank waiting for another's compile on a busy machine


def smooth_field(x: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """A smooth, partition-independent vector field (``coeffs``: 3 x 4)."""
    out = np.zeros((3, x.shape[1]))
    for i in range(3):
        a = coeffs[i]
        out[i] = a[0] * x[0] + a[1] * x[1] ** 2 + a[2] * np.sin(3 * x[0] + x[2]) + a[3] * x[0] * x[1] * x[2]
    return out


def rates(errors: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Observed orders between consecutive steps."""
    return np.log(errors[:-1] / errors[1:]) / np.log(steps[:-1] / steps[1:])


def taylor_rates(
    energy_density: Callable[[dmesh.Mesh], Callable[[Any], Any]],
    steps: np.ndarray,
    stretch: float = 0.3,
    amplitude: float = 0.08,
) -> tuple[np.ndarray, np.ndarray]:
    """Energy → residual and residual → tangent rates of :math:`\\int\\psi(F(u))\\,dx` on a 2 x 1 x 1 box.

    Args:
        energy_density: ``mesh -> psi``, ``psi(F)`` a UFL energy density (built on the mesh, e.g. with fibre fields).
        steps: The step sizes :math:`h`.
        stretch: The mean stretch along x of the state, added to a random field of ``amplitude``.
    """
    comm = MPI.COMM_WORLD
    mesh = dmesh.create_box(comm, [np.zeros(3), np.array([1.0, 0.5, 0.5])], [2, 1, 1], dmesh.CellType.tetrahedron)
    psi = energy_density(mesh)
    V = fem.functionspace(mesh, ("Lagrange", 1, (3,)))
    u, du = fem.Function(V), fem.Function(V)
    rng = np.random.default_rng(17)  # same numbers on every rank
    cu, cd = amplitude * rng.standard_normal((3, 4)), rng.standard_normal((3, 4))
    u.interpolate(lambda x: smooth_field(x, cu) + np.array([[stretch], [0.0], [0.0]]) * x[0])
    du.interpolate(lambda x: smooth_field(x, cd))
    u0 = u.x.array.copy()
    dx = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 1})  # P1: F is constant per cell
    Pi = psi(deformation_gradient(u)) * dx
    R = ufl.derivative(Pi, u, ufl.TestFunction(V))
    Kdu_form = ufl.action(ufl.derivative(R, u, ufl.TrialFunction(V)), du)
    forms = [fem.form(f, jit_options=JIT_OPTIONS) for f in (Pi, R, Kdu_form)]
    n = V.dofmap.index_map.size_local * V.dofmap.index_map_bs

    def at(h: float) -> None:
        u.x.array[:] = u0 + h * du.x.array
        u.x.scatter_forward()

    def energy(h: float) -> float:
        at(h)
        return comm.allreduce(fem.assemble_scalar(forms[0]), op=MPI.SUM)

    def assemble(form: fem.Form) -> np.ndarray:
        b = fem.assemble_vector(form)
        b.scatter_reverse(la.InsertMode.add)
        return b.array[:n].copy()

    def residual(h: float) -> np.ndarray:
        at(h)
        return assemble(forms[1])

    def dot(a: np.ndarray, b: np.ndarray) -> float:
        return comm.allreduce(float(np.dot(a, b)), op=MPI.SUM)

    R0 = residual(0.0)
    at(0.0)
    Kdu = assemble(forms[2])
    assert np.all(np.isfinite(R0)) and np.all(np.isfinite(Kdu))
    Pi0, dPi = energy(0.0), dot(R0, du.x.array[:n])
    assert abs(dPi) > 1e-3
    e0 = np.array([abs(energy(h) - Pi0 - h * dPi) for h in steps])
    e1 = np.array([math.sqrt(dot(r, r)) for r in (residual(h) - R0 - h * Kdu for h in steps)])
    u.x.array[:] = 0.0  # F = I: the tangent has no NaN
    u.x.scatter_forward()
    assert np.all(np.isfinite(assemble(forms[2])))
    return rates(e0, steps), rates(e1, steps)
