r"""Hexahedral (and quadrilateral) meshes through the API (issue 17, item 2).

On a hexahedron a quadrature degree counts per direction and :math:`F` of
:math:`Q_1` is not constant per cell, so the simplex default (one point for
degree 1) left hourglass modes: the bend cantilever on a Q1 box gave
arbitrary answers or no convergence. The default is now the full
:math:`(k+1)^d` Gauss rule (degree :math:`2k`), and reduced rules on
tensor-product cells are refused.

* the rule per cell type, the refusal of reduced rules;
* the Q1 tangent of a free body has exactly the six rigid-body null modes;
* affine patch tests, exact at every node and in the assembled energy:
  Q1 and Q2 on a box and on a distorted (trilinear) hexahedral mesh, Q1 on
  quadrilaterals, the mixed (u, p, θ) Q2/Q1/Q1 problem, fixed-corotated Q1;
* the bend cantilever on hexahedra against the tetrahedral P2 reference;
* the exact step filter is P1-simplex only, the mass of a distorted mesh.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem.cases import MESH_CONVERGENCE, REFERENCE, TEST_POINT, CantileverSpec, bend_load
from hyperfem.dynamics import MassDensity, lumped_mass, total_mass
from hyperfem.errors import ParameterError
from hyperfem.io.probes import PointProbe
from hyperfem.materials import LameParameters, neo_hookean
from hyperfem.materials.fixed_corotated import FixedCorotated
from hyperfem.materials.polar import RotationField
from hyperfem.problem import MixedHyperelasticProblem, SplitEnergy, default_quadrature_degree
from hyperfem.solver.step_filter import StepFilter

HEX = dmesh.CellType.hexahedron
PARAMS = LameParameters.from_youngs(E=1e6, nu=0.3)
TIGHT = {"snes_rtol": 1e-12, "snes_atol": 1e-9}
A3 = np.array([[0.10, -0.05, 0.08], [0.04, -0.12, 0.03], [-0.06, 0.07, 0.15]])
B3 = np.array([0.01, -0.02, 0.03])
EVERYWHERE = {"boundary": lambda x: np.full(x.shape[1], True)}


def _box(n: int, distorted: bool = False, extent=(1.0, 0.8, 0.6)) -> hf.Domain:
    """An n×n×n hexahedral box; ``distorted``: interior nodes moved, every cell a general trilinear map."""
    L = np.array(extent)
    mesh = dmesh.create_box(MPI.COMM_WORLD, [np.zeros(3), L], [n, n, n], HEX)
    if distorted:
        x = mesh.geometry.x
        bump = np.prod(np.sin(np.pi * x / L), axis=1)  # zero on the boundary: the box keeps its volume
        wiggle = np.stack(
            [np.sin(5 * x[:, 0] + 1), np.cos(3 * x[:, 1] + 2 * x[:, 2]), np.sin(2 * x[:, 0] - 7 * x[:, 2])]
        )
        x += 0.35 / n * bump[:, None] * wiggle.T * L
    return hf.Domain.from_locators(mesh, EVERYWHERE)


def _max_error(u: fem.Function, exact) -> float:
    V = u.function_space
    ue = fem.Function(V)
    ue.interpolate(exact)
    n = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    return V.mesh.comm.allreduce(float(np.max(np.abs(u.x.array[:n] - ue.x.array[:n]), initial=0.0)), op=MPI.MAX)


def _integral(mesh, integrand, degree: int) -> float:
    form = fem.form(integrand * ufl.dx(domain=mesh, metadata={"quadrature_degree": degree}))
    return mesh.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)


def _affine(A, b):
    d = len(b)
    return lambda x: A @ x[:d] + b[:, None]


# -- the rule -------------------------------------------------------------------------------------
def test_default_rule_per_cell_type():
    # Simplices unchanged: P1 one point, 2k above; tensor-product cells: 2k for every k.
    assert default_quadrature_degree(1) == 1
    assert default_quadrature_degree(2) == 4
    assert default_quadrature_degree(1, dmesh.CellType.tetrahedron) == 1
    assert default_quadrature_degree(1, HEX) == 2
    assert default_quadrature_degree(2, HEX) == 4
    assert default_quadrature_degree(1, dmesh.CellType.quadrilateral) == 2
    problem = hf.HyperelasticProblem(_box(1), lambda F: neo_hookean(F, PARAMS), degree=1)
    assert problem.quadrature_degree == 2
    assert problem.quadrature_points().shape == (8, 3)  # 2 x 2 x 2 Gauss points


@pytest.mark.parametrize("degree,q", [(1, 1), (2, 3)])
def test_reduced_rule_on_hexahedra_refused(degree, q):
    message = rf"quadrature_degree={q} on hexahedron cells .*hourglass.*>= {2 * degree}"
    with pytest.raises(ParameterError, match=message):
        hf.HyperelasticProblem(_box(1), lambda F: neo_hookean(F, PARAMS), degree=degree, quadrature_degree=q)


def test_reduced_rule_refused_for_the_mixed_problem():
    with pytest.raises(ParameterError, match=r"MixedHyperelasticProblem: quadrature_degree=3 on hexahedron"):
        MixedHyperelasticProblem(
            _box(1), SplitEnergy(lambda F: 0.5 * PARAMS.mu * (ufl.tr(F.T * F) - 3), 1e6), quadrature_degree=3
        )


@pytest.mark.serial
def test_q1_tangent_has_only_rigid_body_modes():
    """A free Q1 body: the reference tangent has exactly 6 zero eigenvalues (the one-point rule: hourglass modes)."""
    mesh = dmesh.create_box(MPI.COMM_SELF, [np.zeros(3), np.array([2.0, 1.0, 1.0])], [2, 1, 1], HEX)
    problem = hf.HyperelasticProblem(hf.Domain.from_locators(mesh, {}), lambda F: neo_hookean(F, PARAMS))
    A = fpetsc.assemble_matrix(fem.form(problem.jacobian))
    A.assemble()
    eig = np.linalg.eigvalsh(A.convert("dense").getDenseArray())
    assert np.count_nonzero(np.abs(eig) < 1e-8 * eig.max()) == 6


# -- patch tests ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "degree,n,distorted", [(1, 3, False), (1, 3, True), (2, 2, False), (2, 3, True)],
    ids=["Q1-box", "Q1-trilinear", "Q2-box", "Q2-trilinear"],
)
def test_affine_patch_test_on_hexahedra(degree, n, distorted):
    domain = _box(n, distorted)
    exact = _affine(A3, B3)
    problem = hf.HyperelasticProblem(
        domain, lambda F: neo_hookean(F, PARAMS), bcs=[hf.PrescribedDisplacement("boundary", exact)], degree=degree
    )
    hf.solve_quasistatic(hf.NewtonSolver(problem, TIGHT))
    assert _max_error(problem.u, exact) < 1e-10
    mesh = domain.mesh
    energy = mesh.comm.allreduce(fem.assemble_scalar(fem.form(problem.energy_internal)), op=MPI.SUM)
    psi0 = neo_hookean(fem.Constant(mesh, np.eye(3) + A3), PARAMS)
    assert energy == pytest.approx(0.48 * _integral(mesh, psi0, 0) / _integral(mesh, fem.Constant(mesh, 1.0), 0))
    assert energy == pytest.approx(_integral(mesh, psi0, 2), rel=1e-10)
    if distorted:
        assert _nonaffine(mesh) > 1e-3


def _nonaffine(mesh) -> float:
    """Largest relative change of a cell volume from the midpoint rule to the exact one (0 on parallelepipeds)."""
    Q = fem.functionspace(mesh, ("DG", 0))
    w, n = ufl.TestFunction(Q), Q.dofmap.index_map.size_local
    one, two = (
        fem.assemble_vector(fem.form(w * ufl.dx(metadata={"quadrature_degree": q}))).array[:n] for q in (1, 2)
    )
    return mesh.comm.allreduce(float(np.max(np.abs(one / two - 1.0), initial=0.0)), op=MPI.MAX)


def test_affine_patch_test_on_quadrilaterals():
    mesh = dmesh.create_rectangle(
        MPI.COMM_WORLD, [np.zeros(2), np.array([1.0, 0.7])], [4, 4], dmesh.CellType.quadrilateral
    )
    x = mesh.geometry.x
    x[:, :2] += 0.06 * (np.sin(np.pi * x[:, 0]) * np.sin(np.pi * x[:, 1] / 0.7))[:, None] * np.array([1.0, -0.7])
    domain = hf.Domain.from_locators(mesh, EVERYWHERE)
    exact = _affine(np.array([[0.15, -0.08], [0.06, -0.10]]), np.array([0.02, -0.01]))
    problem = hf.HyperelasticProblem(
        domain, lambda F: neo_hookean(F, PARAMS), bcs=[hf.PrescribedDisplacement("boundary", exact)]
    )
    assert problem.quadrature_degree == 2
    hf.solve_quasistatic(hf.NewtonSolver(problem, TIGHT))
    assert _max_error(problem.u, exact) < 1e-10


def test_mixed_patch_test_on_hexahedra():
    """Q2/Q1/Q1 (u, p, θ) on a distorted hexahedral mesh: exact homogeneous state, θ = det F."""
    domain = _box(3, distorted=True)
    exact = _affine(A3, B3)
    law = SplitEnergy(lambda F: 0.5 * PARAMS.mu * (hf.kinematics.isochoric_invariants(F)[0] - 3.0), 50 * PARAMS.mu)
    problem = MixedHyperelasticProblem(domain, law, bcs=[hf.PrescribedDisplacement("boundary", exact)])
    assert problem.quadrature_degree == 4
    hf.solve_quasistatic(hf.NewtonSolver(problem, TIGHT))
    displacement, _ = problem.update_fields()
    assert _max_error(displacement, exact) < 1e-10
    n = problem.volume.function_space.dofmap.index_map.size_local
    theta = problem.volume.x.array[:n]
    error = np.max(np.abs(theta - np.linalg.det(np.eye(3) + A3)), initial=0.0)
    assert domain.comm.allreduce(error, op=MPI.MAX) < 1e-10


def test_fixed_corotated_patch_test_on_hexahedra():
    """Polar rotation fields on the 2 x 2 x 2 Gauss points of a Q1 hexahedron (not cellwise constant)."""
    domain = _box(3, distorted=True)
    exact = _affine(A3, B3)
    psi = FixedCorotated(PARAMS)
    problem = hf.HyperelasticProblem(domain, psi, bcs=[hf.PrescribedDisplacement("boundary", exact)])
    assert psi.field.quadrature_degree == 2 and not psi.field.rotation.cellwise_constant
    hf.solve_quasistatic(hf.NewtonSolver(problem, TIGHT))
    assert _max_error(problem.u, exact) < 1e-10


def test_rotation_field_default_rule_on_hexahedra():
    """Bound without a degree, the fields sit on the problem's default rule for the cell type."""
    V = fem.functionspace(_box(1).mesh, ("Lagrange", 1, (3,)))
    field = RotationField()
    field.bind(ufl.Identity(3) + ufl.grad(fem.Function(V)))
    assert field.quadrature_degree == 2 and field.rotation.num_points == 8


# -- the cantilever -------------------------------------------------------------------------------
def _bend(n: int, degree: int) -> np.ndarray:
    """Test-point displacement of the bend cantilever on a (5n, 2n, 2n) hexahedral box (h = 2/n)."""
    corners = [np.array([-5.0, -2.0, -2.0]), np.array([5.0, 2.0, 2.0])]
    mesh = dmesh.create_box(MPI.COMM_WORLD, corners, [5 * n, 2 * n, 2 * n], HEX)
    domain = hf.Domain.from_locators(
        mesh, {"clamped": lambda x: np.isclose(x[0], -5.0), "free_end": lambda x: np.isclose(x[0], 5.0)}
    )
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(
        domain, lambda F: neo_hookean(F, params), bcs=[hf.Clamp("clamped")], loads=[bend_load()], degree=degree
    )
    hf.solve_quasistatic(hf.NewtonSolver(problem))
    return PointProbe(mesh, [TEST_POINT])(problem.u)[0]


def test_bend_on_hexahedra_approaches_the_tetrahedral_answer():
    """Q2 on h = 2 within 1.5 % of the P2-tetrahedron reference; Q1 errors fall under refinement (h = 2, 1)."""
    reference = np.array(MESH_CONVERGENCE[("bend", *REFERENCE["bend"])])
    q2 = _bend(1, 2)
    assert abs(q2[1] / reference[1] - 1.0) < 0.015  # measured 0.9 %
    assert np.linalg.norm(q2 - reference) < 0.015 * np.linalg.norm(reference)
    coarse, fine = (abs(_bend(n, 1)[1] / reference[1] - 1.0) for n in (1, 2))
    assert fine < 0.07  # measured 4.6 % (P1 tetrahedra of h = 1: 17 %)
    assert fine < 0.5 * coarse  # measured 14.6 % -> 4.6 %


# -- inversion guard and mass ---------------------------------------------------------------------
def test_exact_step_filter_is_refused_on_hexahedra():
    problem = hf.HyperelasticProblem(_box(1), lambda F: neo_hookean(F, PARAMS), bcs=[hf.Clamp("boundary")])
    assert hf.NewtonSolver(problem).step_filter == "bisection"  # min J at the 2 x 2 x 2 Gauss points
    with pytest.raises(ParameterError, match="step_filter='exact'"):
        hf.NewtonSolver(problem, step_filter="exact")
    with pytest.raises(ParameterError, match="on hexahedron"):
        StepFilter(problem.V)


def test_mass_on_hexahedra():
    domain = _box(3, distorted=True)
    assert total_mass(MassDensity(3.0), domain) == pytest.approx(3.0 * 0.48, rel=1e-12)
    box = _box(2)
    V = fem.functionspace(box.mesh, ("Lagrange", 1))
    m = lumped_mass(MassDensity(3.0, lumped=True), box, V)
    n = V.dofmap.index_map.size_local
    assert box.comm.allreduce(float(m.x.array[:n].sum()), op=MPI.SUM) == pytest.approx(3.0 * 0.48, rel=1e-12)
    assert box.comm.allreduce(float(m.x.array[:n].min()), op=MPI.MIN) > 0.0


def test_a_simulation_runs_on_hexahedra(tmp_path):
    """The run layer took the simplex quality measures and refused hexahedral meshes."""
    from hyperfem.simulation import Probe, Simulation

    box = [[-5.0, -2.0, -2.0], [5.0, 2.0, 2.0]]
    mesh = dmesh.create_box(MPI.COMM_WORLD, box, [10, 4, 4], dmesh.CellType.hexahedron)
    domain = hf.Domain.from_locators(
        mesh, {"clamped": lambda x: np.isclose(x[0], -5.0), "free_end": lambda x: np.isclose(x[0], 5.0)}
    )
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(domain, lambda F: neo_hookean(F, params), bcs=[hf.Clamp("clamped")],
                                     loads=[bend_load()])
    summary = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(), [Probe([TEST_POINT])]).run()
    assert summary["completed"] and summary["mesh_quality"] is None
    assert summary["probe_displacement"][0][1] == pytest.approx(-1.2184, rel=2e-3)  # Q1, h = 1 (see the module)


def test_lumped_mass_on_hexahedra_is_refused_in_implicit_dynamics():
    from hyperfem import dynamics as dyn

    base = hf.HyperelasticProblem(_box(2), lambda F: neo_hookean(F, LameParameters.from_youngs(1e3, 0.3)))
    with pytest.raises(ParameterError, match="lumped mass on hexahedron cells would integrate the elastic energy"):
        dyn.IncrementalProblem(base, dyn.Newmark(), MassDensity(1.0, lumped=True))
    dyn.IncrementalProblem(base, dyn.Newmark(), MassDensity(1.0))  # consistent mass: fine
