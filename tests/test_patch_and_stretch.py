r"""Exactly representable nonlinear solutions.

* Patch test: an affine displacement prescribed on the whole boundary is the
  exact solution of every homogeneous hyperelastic body; the FE solution must
  reproduce it at every node.
* Homogeneous uniaxial stretch of a unit cube/square with symmetry conditions:
  the deformation is :math:`F = \operatorname{diag}(\lambda, \lambda_t, \lambda_t)`
  with the lateral stretch :math:`\lambda_t` from :math:`P_{22} = 0` of the
  closed-form Neo-Hookean stress, solved independently here with numpy.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.materials import LameParameters, neo_hookean

PARAMS = LameParameters.from_youngs(E=1e6, nu=0.3)
TIGHT = {"snes_rtol": 1e-12, "snes_atol": 1e-9}  # residuals are O(E * h^2) ~ 1e4


def _max_error(domain: hf.Domain, u: fem.Function, exact) -> float:
    """Largest nodal error over owned dofs, all ranks."""
    V = u.function_space
    ue = fem.Function(V)
    ue.interpolate(exact)
    n = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    local = np.max(np.abs(u.x.array[:n] - ue.x.array[:n]), initial=0.0)
    return domain.comm.allreduce(local, op=MPI.MAX)


# --------------------------------------------------------------------------
# Patch test
# --------------------------------------------------------------------------
@pytest.mark.parametrize(
    "dim,degree", [(3, 1), (3, 2), (2, 1)], ids=["3d-P1", "3d-P2", "2d-P1"]
)
def test_affine_patch_test(dim, degree):
    comm = MPI.COMM_WORLD
    if dim == 3:
        mesh = dmesh.create_box(comm, [np.zeros(3), np.array([1.0, 0.8, 0.6])], [3, 3, 3])
        A = np.array([[0.10, -0.05, 0.08], [0.04, -0.12, 0.03], [-0.06, 0.07, 0.15]])
        b = np.array([0.01, -0.02, 0.03])
    else:
        mesh = dmesh.create_rectangle(comm, [np.zeros(2), np.array([1.0, 0.7])], [4, 4])
        A = np.array([[0.15, -0.08], [0.06, -0.10]])
        b = np.array([0.02, -0.01])
    assert np.linalg.det(np.eye(dim) + A) > 0.5

    def affine(x):
        return A @ x[:dim] + b[:, None]

    domain = hf.Domain.from_locators(mesh, {"boundary": lambda x: np.full(x.shape[1], True)})
    problem = hf.HyperelasticProblem(
        domain,
        lambda F: neo_hookean(F, PARAMS),
        bcs=[hf.PrescribedDisplacement("boundary", affine)],
        degree=degree,
    )
    # Interior nodes exist and start away from the solution.
    V = problem.V
    bdofs = fem.locate_dofs_topological(V, dim - 1, domain.facets("boundary"))
    n_owned = V.dofmap.index_map.size_local
    interior_local = n_owned - np.count_nonzero(bdofs < n_owned)
    assert comm.allreduce(interior_local, op=MPI.SUM) >= 8

    solver = hf.NewtonSolver(problem, TIGHT)
    steps = hf.solve_quasistatic(solver)
    assert steps and steps[-1].time == pytest.approx(1.0)
    assert all(s.solve.converged for s in steps)
    err = _max_error(domain, problem.u, affine)
    assert err < 1e-10, err
    # The deformation is far from trivial.
    assert np.abs(A).max() > 0.1


# --------------------------------------------------------------------------
# Uniaxial stretch
# --------------------------------------------------------------------------
STRETCH = 1.3


def _nh_uniaxial(stretch: float, dim: int, mu: float, lam: float) -> tuple[float, float]:
    r"""Lateral stretch and nominal stress P11 of NH uniaxial stress.

    P22 = mu*t + (lam*ln J - mu)/t = 0 with J = stretch * t^(dim-1), solved by
    safeguarded Newton (bisection fallback) with numpy only.
    """

    def g(t):
        J = stretch * t ** (dim - 1)
        return mu * t + (lam * np.log(J) - mu) / t

    def dg(t):
        J = stretch * t ** (dim - 1)
        return mu - (lam * np.log(J) - mu) / t**2 + lam * (dim - 1) / t**2

    lo, hi = 1e-3, 1.0 / np.sqrt(stretch) * 2.0  # g(lo) < 0 < g(hi)
    assert g(lo) < 0 < g(hi)
    t = 1.0
    for _ in range(100):
        step = g(t) / dg(t)
        t_new = t - step
        if not lo < t_new < hi:
            t_new = 0.5 * (lo + hi)
        if g(t_new) > 0:
            hi = t_new
        else:
            lo = t_new
        if abs(t_new - t) < 1e-15 * t:
            t = t_new
            break
        t = t_new
    assert abs(g(t)) < 1e-9 * mu
    J = stretch * t ** (dim - 1)
    P11 = mu * stretch + (lam * np.log(J) - mu) / stretch
    return t, P11


def test_analytic_uniaxial_reference():
    """The numpy reference itself: small stretch recovers Poisson's ratio and E."""
    eps = 1e-6
    t, P11 = _nh_uniaxial(1 + eps, 3, PARAMS.mu, PARAMS.lmbda)
    assert (1 - t) / eps == pytest.approx(0.3, rel=1e-5)
    assert P11 / eps == pytest.approx(1e6, rel=1e-5)
    # plane strain: nu' = nu/(1-nu), E' = E/(1-nu^2)
    t, P11 = _nh_uniaxial(1 + eps, 2, PARAMS.mu, PARAMS.lmbda)
    assert (1 - t) / eps == pytest.approx(0.3 / 0.7, rel=1e-5)
    assert P11 / eps == pytest.approx(1e6 / (1 - 0.09), rel=1e-5)


@pytest.mark.parametrize("dim", [3, 2], ids=["3d", "plane-strain"])
def test_uniaxial_stretch(dim):
    comm = MPI.COMM_WORLD
    if dim == 3:
        mesh = dmesh.create_unit_cube(comm, 2, 2, 2)
    else:
        mesh = dmesh.create_unit_square(comm, 3, 3)
    locators = {
        "x0": lambda x: np.isclose(x[0], 0.0),
        "y0": lambda x: np.isclose(x[1], 0.0),
        "x1": lambda x: np.isclose(x[0], 1.0),
    }
    if dim == 3:
        locators["z0"] = lambda x: np.isclose(x[2], 0.0)
    domain = hf.Domain.from_locators(mesh, locators)
    bcs = [
        hf.PrescribedDisplacement("x0", [0.0], components=[0]),
        hf.PrescribedDisplacement("y0", [0.0], components=[1]),
        hf.PrescribedDisplacement("x1", [STRETCH - 1.0], components=[0]),
    ]
    if dim == 3:
        bcs.append(hf.PrescribedDisplacement("z0", [0.0], components=[2]))
    psi = lambda F: neo_hookean(F, PARAMS)  # noqa: E731
    problem = hf.HyperelasticProblem(domain, psi, bcs=bcs)
    solver = hf.NewtonSolver(problem, TIGHT)
    steps = hf.solve_quasistatic(solver)
    assert steps[-1].time == pytest.approx(1.0)

    lam_t, P11_exact = _nh_uniaxial(STRETCH, dim, PARAMS.mu, PARAMS.lmbda)
    assert 0.7 < lam_t < 0.95  # a real lateral contraction

    # Whole displacement field: u = (F - I) X with F = diag(1.3, t, t).
    Fexact = np.diag([STRETCH] + [lam_t] * (dim - 1))
    err = _max_error(domain, problem.u, lambda x: (Fexact - np.eye(dim)) @ x[:dim])
    assert err < 1e-9, err

    # Lateral stretch from the FE solution: displacement of the y = 1 face.
    V = problem.V
    y1 = dmesh.locate_entities_boundary(mesh, dim - 1, lambda x: np.isclose(x[1], 1.0))
    dofs_y1 = fem.locate_dofs_topological(V, dim - 1, y1)
    owned = dofs_y1[dofs_y1 < V.dofmap.index_map.size_local]
    uy = problem.u.x.array.reshape(-1, dim)[owned, 1]
    lo = comm.allreduce(np.min(uy, initial=np.inf), op=MPI.MIN)
    hi = comm.allreduce(np.max(uy, initial=-np.inf), op=MPI.MAX)
    assert 1.0 + lo == pytest.approx(lam_t, rel=1e-10)
    assert 1.0 + hi == pytest.approx(lam_t, rel=1e-10)

    # Nominal stress from the surface integral of P11 = dpsi/dF_11 on x = 1 (area 1).
    Fv = ufl.variable(problem.F)
    P = ufl.diff(psi(Fv), Fv)
    P11_face = comm.allreduce(
        fem.assemble_scalar(fem.form(P[0, 0] * domain.ds("x1"))), op=MPI.SUM
    )
    assert P11_face == pytest.approx(P11_exact, rel=1e-8)

    # Reaction force: residual at the x-dofs of x = 1 (Dirichlet left out of the
    # assembly), summed over the face.
    R = fpetsc.assemble_vector(fem.form(problem.residual))
    R.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    V0 = V.sub(0).collapse()[0]
    dofs_x1 = fem.locate_dofs_topological((V.sub(0), V0), dim - 1, domain.facets("x1"))[0]
    n_owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    local = R.array_r[dofs_x1[dofs_x1 < n_owned]].sum()
    reaction = comm.allreduce(local, op=MPI.SUM)
    assert reaction == pytest.approx(P11_exact, rel=1e-8)
    # Free dofs are in equilibrium: the residual vanishes away from the constrained dofs.
    free = np.ones(n_owned, dtype=bool)
    for bc in problem.bcs:
        dofs = bc.dof_indices()[0]
        free[dofs[dofs < n_owned]] = False
    res_free = comm.allreduce(np.max(np.abs(R.array_r[free]), initial=0.0), op=MPI.MAX)
    assert res_free < 1e-8 * abs(P11_exact)
    R.destroy()
