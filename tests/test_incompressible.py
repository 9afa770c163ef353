r"""Nearly incompressible uniaxial stretch and compression of a cube (issue 8).

Unit cube of tetrahedra, rollers on :math:`x = 0`, :math:`y = 0`, :math:`z = 0`,
:math:`u_x = \lambda - 1` on :math:`x = 1`, lateral faces free, Neo-Hookean
:math:`\psi_\text{iso} = \frac{\mu}{2}(J^{-2/3}\operatorname{tr}C - 3)` plus every
volumetric law :math:`U(J)`. The exact solution is homogeneous,
:math:`F = \operatorname{diag}(\lambda, s, s)`, and lies in every finite-element
space used here, so each node must reproduce it:

* (a) to :math:`10^{-6}` against the compressible solution: :math:`s` from
  :math:`\partial W/\partial s = 0` with :math:`W(s) = \frac{\mu}{2}(J^{-2/3}(\lambda^2 +
  2s^2) - 3) + U(J)`, :math:`J = \lambda s^2`, by bisection on the explicit
  :math:`\partial W/\partial s = \frac{\mu}{2}J^{-2/3}(4s - \frac{4}{3}I_1/s) +
  2\lambda s\,U'(J)`; the axial force is :math:`P_{11} = \frac{\mu}{2}J^{-2/3}(2\lambda -
  \frac{2}{3}I_1/\lambda) + s^2U'(J)` (unit face), the pressure :math:`U'(J)`;
* (b) to 0.5 % against the incompressible limit at :math:`K/\mu = 10^3`: lateral
  displacement :math:`1/\sqrt\lambda - 1` on the free faces, axial force
  :math:`\mu(\lambda - \lambda^{-2})`.

Cases. Mixed (three-field) formulation: every law on 2×2×2 (stretch 2 and
compression 0.5) and 4×4×4 (stretch 2 and compression 0.6), and the ``log`` law
at stretch 2 on 8×8×8 (the slowest case, ~15 s). Left out to keep the file
fast: the other laws on 8×8×8, and compression 0.5 on 4×4×4 and finer. The
latter is not a homogeneous problem any more: the homogeneous compressed state
loses stability near :math:`\lambda = 0.53` (the *conforming* P2 displacement
discretisation on 8×8×8 already has a negative eigenvalue of the tangent at
0.53, none at 0.55, so this is the continuum, not the element), and the
three-field tangent on 4×4×4 has one from 0.53 on; a solver may then leave the
homogeneous branch. The displacement formulation (P1): 2×2×2 only; its
:math:`K/\mu = 10^4` stretch waits for the boundary-lifting predictor.

Cause of the failure these tests catch (the old two-field form
:math:`\int\psi_\text{iso} + p\ln J - p^2/2K`): ``test_homogeneous_stretch_stability``
shows that its homogeneous state at stretch 2 on 4×4×4 was a *saddle* of the
discrete problem (one negative eigenvalue of the condensed tangent), so Newton
found a lower, non-homogeneous state (:math:`\int J\,dX = 1.07`); the three-field
tangent there is positive definite. ``test_check_solution_flags_intra_cell_oscillation``
checks that a state of that kind (:math:`J` oscillating inside the cells) is
rejected by :meth:`~hyperfem.problem.MixedHyperelasticProblem.check_solution`.
"""

from __future__ import annotations

import math

import basix.ufl
import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem

import hyperfem as hf
from hyperfem.solver.inertia import negative_pivots
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube
from hyperfem.kinematics import isochoric_invariants
from hyperfem.materials.volumetric import VOLUMETRIC_LAWS
from hyperfem.problem import SplitEnergy, solid_problem
from hyperfem.problem.mixed import VOLUME_CONSISTENCY_LIMIT
from hyperfem.simulation.reactions import ReactionForce

MU = 1.0
LAWS = sorted(VOLUMETRIC_LAWS)

# U'(J) of each law, written out independently of the UFL definitions.
DU = {
    "log": lambda J, K: K * math.log(J) / J,
    "quadratic": lambda J, K: K * (J - 1.0),
    "simo_taylor": lambda J, K: 0.5 * K * (J - 1.0 / J),
}


_cube = unit_cube
_rollers = uniaxial_rollers


def _material(K: float, law: str) -> SplitEnergy:
    return SplitEnergy(lambda F: 0.5 * MU * (isochoric_invariants(F)[0] - 3.0), K, law)


def uniaxial_compressible(lam: float, K: float, law: str) -> tuple[float, float, float]:
    """Lateral stretch ``s``, axial force ``P11`` and pressure ``U'(J)`` of the homogeneous state."""

    def dWds(s):
        J = lam * s * s
        I1 = lam**2 + 2.0 * s * s
        return 0.5 * MU * J ** (-2.0 / 3.0) * (4.0 * s - 4.0 / 3.0 * I1 / s) + 2.0 * lam * s * DU[law](J, K)

    lo, hi = 0.3, 2.0
    assert dWds(lo) < 0.0 < dWds(hi)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if dWds(mid) < 0.0 else (lo, mid)
    s = 0.5 * (lo + hi)
    J = lam * s * s
    I1 = lam**2 + 2.0 * s * s
    P11 = 0.5 * MU * J ** (-2.0 / 3.0) * (2.0 * lam - 2.0 / 3.0 * I1 / lam) + s * s * DU[law](J, K)
    return s, P11, DU[law](J, K)


def _owned(f: fem.Function) -> np.ndarray:
    imap = f.function_space.dofmap.index_map
    bs = f.function_space.dofmap.index_map_bs
    return f.x.array[: imap.size_local * bs]


def _max(comm, values: np.ndarray) -> float:
    return comm.allreduce(float(np.max(values, initial=0.0)), op=MPI.MAX)


def _solve(n: int, lam: float, K: float, law: str, formulation: str):
    domain = _cube(n)
    problem = solid_problem(domain, _material(K, law), formulation=formulation, bcs=_rollers(lam))
    steps = hf.solve_quasistatic(hf.NewtonSolver(problem), stepping=hf.LoadStepping(initial_increment=0.25))
    u = problem.update_fields()[0] if formulation == "mixed" else problem.u
    return domain, problem, u, steps


def _check_uniaxial(domain, problem, u, lam: float, K: float, law: str) -> None:
    comm = domain.comm
    s, P11, pressure = uniaxial_compressible(lam, K, law)
    x = u.function_space.tabulate_dof_coordinates()[: _owned(u).size // 3]
    uh = _owned(u).reshape(-1, 3)
    exact = np.column_stack([(lam - 1.0) * x[:, 0], (s - 1.0) * x[:, 1], (s - 1.0) * x[:, 2]])
    force = ReactionForce(problem, "x1")()[0]

    # (a) the compressible solution, at every node
    assert _max(comm, np.abs(uh - exact)) < 1e-6
    assert force == pytest.approx(P11, rel=1e-6)
    # (b) the incompressible limit on the free faces, and the axial force
    lateral = 1.0 / math.sqrt(lam) - 1.0
    on_y1, on_z1 = np.isclose(x[:, 1], 1.0), np.isclose(x[:, 2], 1.0)
    assert comm.allreduce(int(on_y1.sum() + on_z1.sum())) > 0
    deviation = np.concatenate([uh[on_y1, 1], uh[on_z1, 2]]) / lateral - 1.0
    assert _max(comm, np.abs(deviation)) < 5e-3
    assert force == pytest.approx(MU * (lam - lam**-2), rel=5e-3)

    if getattr(problem, "saddle_point", False):
        assert _max(comm, np.abs(_owned(problem.pressure) / pressure - 1.0)) < 1e-6
        assert _max(comm, np.abs(_owned(problem.volume) - lam * s * s)) < 1e-8
        indicators, message = problem.check_solution()
        assert message is None and indicators["volume_consistency"] < 1e-8


MIXED_CASES = [(n, lam, law) for n, lam in [(2, 2.0), (2, 0.5), (4, 2.0), (4, 0.6)] for law in LAWS]
# The failing row of issue 8 (the slowest case): serial only. Under mpiexec -n 2 the three-field
# solve on a partitioned cube is covered by the 2x2x2 and 4x4x4 rows above (same law, same stretch).
MIXED_CASES.append(pytest.param(8, 2.0, "log", marks=pytest.mark.serial))


def _case_id(case) -> str:
    n, lam, law = case.values if hasattr(case, "values") else case
    return f"n{n}-stretch{lam}-{law}"


@pytest.mark.parametrize(("n", "lam", "law"), MIXED_CASES, ids=[_case_id(c) for c in MIXED_CASES])
def test_mixed_uniaxial(n, lam, law):
    """Three-field formulation, :math:`K/\\mu = 10^3`: homogeneous at every node, (a) and (b)."""
    K = 1e3
    domain, problem, u, _ = _solve(n, lam, K, law, "mixed")
    _check_uniaxial(domain, problem, u, lam, K, law)


DISPLACEMENT_CASES = [
    pytest.param(2, 2.0, 1e3, id="2-stretch2-K1e3"),
    pytest.param(2, 0.5, 1e3, id="2-stretch0.5-K1e3"),
    pytest.param(2, 2.0, 1e4, id="2-stretch2-K1e4"),
    pytest.param(4, 2.0, 1e4, id="4-stretch2-K1e4"),
    pytest.param(8, 2.0, 1e4, id="8-stretch2-K1e4"),
]


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize(("n", "lam", "K"), DISPLACEMENT_CASES)
def test_displacement_uniaxial(n, lam, K, law):
    """P1 displacement formulation; stretch 2 within 8 load steps and 60 Newton iterations.

    Without the boundary-increment predictor of the solver the 4x4x4, K/μ = 10⁴ case took
    129 load steps and 1,255 Newton iterations.
    """
    domain, problem, u, steps = _solve(n, lam, K, law, "displacement")
    _check_uniaxial(domain, problem, u, lam, K, law)
    if lam == 2.0 and K == 1e4:
        assert len(steps) <= 8
        assert sum(st.solve.iterations for st in steps) <= 60


def _homogeneous_state(problem, lam: float, K: float, law: str) -> None:
    """Put the exact homogeneous solution into the mixed unknown of ``problem``."""
    s, _, pressure = uniaxial_compressible(lam, K, law)
    uh = fem.Function(problem.V)
    uh.interpolate(lambda x: np.vstack([(lam - 1.0) * x[0], (s - 1.0) * x[1], (s - 1.0) * x[2]]))
    problem.u.x.array[problem._u_dofs] = uh.x.array
    problem.u.x.array[problem._p_dofs] = pressure
    problem.u.x.array[problem._theta_dofs] = lam * s * s - 1.0


def _negative_eigenvalues(jacobian: ufl.Form, bcs, pressure_dofs: int) -> int:
    """Negative eigenvalues of the tangent condensed on the displacement (MUMPS LDL^T inertia).

    The pressure block :math:`-M/K` of the two-field form, and the pressure–volume
    block :math:`[[0, -M], [-M, U''M]]` of the three-field form, each have
    ``pressure_dofs`` negative eigenvalues (Haynsworth: inertia adds over the
    Schur complement); Dirichlet rows are unit diagonal.
    """
    A = fpetsc.assemble_matrix(fem.form(jacobian), bcs=bcs)
    A.assemble()
    negative = negative_pivots(A)
    A.destroy()
    return negative - pressure_dofs


def _two_field_log_tangent(problem, K: float):
    """Tangent of the old form :math:`\\int\\psi_\\text{iso} + p\\ln J - p^2/2K` at the state of ``problem``."""
    mesh = problem.domain.mesh
    cell = mesh.basix_cell()
    el_u = basix.ufl.element("Lagrange", cell, 2, shape=(3,))
    W = fem.functionspace(mesh, basix.ufl.mixed_element([el_u, basix.ufl.element("Lagrange", cell, 1)]))
    w = fem.Function(W)
    for i, field in enumerate((problem.displacement_field, problem.volume)):
        V, dofs = W.sub(i).collapse()
        copy = fem.Function(V)
        copy.interpolate(field)
        w.x.array[dofs] = copy.x.array if i == 0 else K * np.log(copy.x.array)
    u, p = ufl.split(w)
    F = ufl.Identity(3) + ufl.grad(u)
    psi = 0.5 * MU * (isochoric_invariants(F)[0] - 3.0) + p * ufl.ln(ufl.det(F)) - p**2 / (2.0 * K)
    Pi = psi * ufl.dx(metadata={"quadrature_degree": problem.quadrature_degree})
    jacobian = ufl.derivative(ufl.derivative(Pi, w), w)
    bcs = []
    for i, where in enumerate(("x0", "y0", "z0", "x1")):
        dofs = fem.locate_dofs_topological(W.sub(0).sub(i % 3), 2, problem.domain.facets(where))
        bcs.append(fem.dirichletbc(0.0, dofs, W.sub(0).sub(i % 3)))
    return jacobian, bcs


def test_homogeneous_stretch_stability():
    """Stretch 2 on 4×4×4, K/mu = 1e3: the old ln J two-field state is a saddle, the three-field one a minimum."""
    K, lam = 1e3, 2.0
    domain = _cube(4)
    problem = solid_problem(domain, _material(K, "log"), bcs=_rollers(lam))
    problem.set_time(1.0)
    _homogeneous_state(problem, lam, K, "log")
    problem.update_fields()
    nq = problem.Q.dofmap.index_map.size_global
    assert _negative_eigenvalues(problem.jacobian, problem.bcs, nq) == 0
    jacobian, bcs = _two_field_log_tangent(problem, K)
    assert _negative_eigenvalues(jacobian, bcs, nq) == 1


def test_check_solution_flags_intra_cell_oscillation():
    """J oscillating inside the cells (the old failure mode) is rejected; the homogeneous state is not.

    The perturbation moves only the edge-midpoint nodes of the P2 displacement:
    its vertex values, hence anything a P1 field can see of it, are unchanged,
    and :math:`\\theta` is the best P1 fit of the new :math:`J`.
    """
    K, lam, n = 1e3, 2.0, 2
    domain = _cube(n)
    problem = solid_problem(domain, _material(K, "log"), bcs=_rollers(lam))
    _homogeneous_state(problem, lam, K, "log")
    indicators, message = problem.check_solution()
    assert message is None and indicators["volume_consistency"] < 1e-12

    uh = fem.Function(problem.V)
    uh.x.array[:] = problem.u.x.array[problem._u_dofs]
    x = problem.V.tabulate_dof_coordinates()
    midpoint = np.any(np.abs(n * x - np.round(n * x)) > 1e-8, axis=1)
    wobble = 0.03 * np.sin(37.0 * x[:, 0] + 11.0 * x[:, 1] + 5.0 * x[:, 2])
    uh.x.array.reshape(-1, 3)[midpoint] += wobble[midpoint, None] * np.array([1.0, -1.0, 0.5])
    problem.u.x.array[problem._u_dofs] = uh.x.array
    md = {"quadrature_degree": problem.quadrature_degree}
    theta, tau = ufl.TrialFunction(problem.Q), ufl.TestFunction(problem.Q)
    J = ufl.det(ufl.Identity(3) + ufl.grad(uh))
    fit = fpetsc.LinearProblem(
        theta * tau * ufl.dx(metadata=md),
        J * tau * ufl.dx(metadata=md),
        petsc_options_prefix="test_volume_fit_",
        petsc_options={"ksp_type": "preonly", "pc_type": "lu"},
    ).solve()
    problem.u.x.array[problem._theta_dofs] = fit.x.array - 1.0
    indicators, message = problem.check_solution()
    assert indicators["volume_consistency"] > 2.0 * VOLUME_CONSISTENCY_LIMIT
    assert message is not None and "volume" in message


def test_volume_jacobian_guards_theta():
    """The solver's inversion guard sees min(J, theta): a shrinking volume field counts as inversion."""
    domain = _cube(2)
    problem = solid_problem(domain, _material(1e3, "log"), bcs=_rollers(1.0))
    problem.u.x.array[problem._theta_dofs] = -0.75  # theta = 0.25, J = 1
    expr = fem.Expression(problem.volume_jacobian(), problem.quadrature_points())
    cells = np.arange(domain.mesh.topology.index_map(3).size_local, dtype=np.int32)
    values = expr.eval(domain.mesh, cells)
    assert domain.comm.allreduce(float(values.max()), op=MPI.MAX) == pytest.approx(0.25)
