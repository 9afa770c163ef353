"""The iterative and the direct tangent solves give the same outcome on the hard cases.

Above :data:`~hyperfem.solver.linear.DIRECT_THRESHOLD` unknowns Newton's
tangent is solved by CG (GMRES with follower loads) + GAMG (P1) or the p-multigrid (P2 and up), or by the Schur
field split for the mixed problem, to a relative tolerance of 1e-6. A month
after the switch a bend at load increment 0.001 failed at once on that path
(``DIVERGED_LINE_SEARCH`` at ``|r| = 0.07``) while MUMPS converged: the AMG-preconditioned
Krylov solve left errors of the order of its tolerance in the Dirichlet rows
of the Newton step, the energy line search accepted steps that moved the
clamped nodes (lowering Π below its constrained minimum), and Newton stalled
at a residual that was all boundary rows.

Each case here runs with the automatic choice forced onto the iterative path
(``threshold=0``: the meshes are small) and with MUMPS, and must end the same:
both converge, to the same state. Tiny and full increments, P1–P3, dead and
follower loads, the mixed (u, p, θ) formulation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

import hyperfem as hf
from hyperfem.cases import CantileverSpec
from hyperfem.kinematics import isochoric_invariants
from hyperfem.problem import SplitEnergy, solid_problem
from hyperfem.solver.linear import DIRECT, choose_linear_solver, describe

MESHES = Path(__file__).resolve().parent.parent / "meshes"
PARAMS = CantileverSpec().lame


def _neo_hookean(F):
    return hf.materials.neo_hookean(F, PARAMS)


def _bend(domain, degree: int, follower: bool):
    load = hf.FollowerTraction if follower else hf.DeadTraction
    return hf.HyperelasticProblem(
        domain, _neo_hookean, degree=degree, bcs=[hf.Clamp("clamped")],
        loads=[load("free_end", (0.0, -5e3, 0.0))],
    )


def _twist(domain, degree: int, follower: bool):
    """The twist of the issue's cantilever: a follower traction, a markedly non-symmetric tangent."""
    from hyperfem.cases import twist_load

    assert follower
    return hf.HyperelasticProblem(domain, _neo_hookean, degree=degree, bcs=[hf.Clamp("clamped")], loads=[twist_load()])


def _mixed_bend(domain, degree: int, follower: bool):
    iso = lambda F: 0.5 * PARAMS.mu * (isochoric_invariants(F)[0] - 3.0)  # noqa: E731
    load = hf.FollowerTraction if follower else hf.DeadTraction
    return solid_problem(
        domain, SplitEnergy(iso, 100.0 * PARAMS.mu), formulation="mixed", bcs=[hf.Clamp("clamped")],
        loads=[load("free_end", (0.0, -5e3, 0.0))],
    )


CASES = {
    # name: (mesh, problem builder, degree, follower, load factor of one step).
    # On beam_h1 the tiny dead-load steps stalled on the iterative path before the fix (P1: 50
    # iterations at |r| = 0.125; P2: DIVERGED_LINE_SEARCH at 0.125); beam_h2 is too coarse to show it.
    "P1-dead-tiny": ("beam_h1", _bend, 1, False, 1e-3),
    "P2-dead-tiny": ("beam_h1", _bend, 2, False, 1e-3),
    "P2-dead-tinier": ("beam_h1", _bend, 2, False, 1e-4),
    "P2-dead-full": ("beam_h2", _bend, 2, False, 1.0),
    "P3-dead-full": ("beam_h2", _bend, 3, False, 1.0),
    "P2-follower-tiny": ("beam_h1", _bend, 2, True, 1e-3),
    "P2-follower-tinier": ("beam_h1", _bend, 2, True, 1e-4),
    "P2-follower-full": ("beam_h2", _bend, 2, True, 1.0),
    "P3-follower-full": ("beam_h2", _bend, 3, True, 1.0),
    "P2-twist-full": ("beam_h2", _twist, 2, True, 1.0),
    "mixed-dead-tiny": ("beam_h1", _mixed_bend, 2, False, 1e-3),
    "mixed-dead-full": ("beam_h2", _mixed_bend, 2, False, 1.0),
}


def _run(domain, case: str, path: str):
    _, build, degree, follower, factor = CASES[case]
    problem = build(domain, degree, follower)
    if path == "iterative":
        solver = hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, threshold=0, mixed_threshold=0))
        assert "lu" not in solver.linear_solver_name
    else:
        solver = hf.NewtonSolver(problem, petsc_options=dict(DIRECT))
    steps = hf.solve_quasistatic(solver, target=factor, stepping=hf.LoadStepping(initial_increment=factor,
                                                                                   min_increment=factor / 64,
                                                                                   max_increment=factor))
    assert problem.time == pytest.approx(factor)
    return problem, steps


@pytest.fixture(scope="module")
def meshes():
    return {name: hf.read_mesh(MESHES / f"{name}.msh", MPI.COMM_WORLD) for name in ("beam_h1", "beam_h2")}


@pytest.mark.parametrize("case", list(CASES))
def test_iterative_and_direct_tangent_solves_end_the_same(meshes, case):
    beam = meshes[CASES[case][0]]
    iterative, steps_i = _run(beam, case, "iterative")
    direct, steps_d = _run(beam, case, "direct")
    # A tiny increment is one easy step on either path; it must not be cut back.
    if CASES[case][4] < 1:
        assert len(steps_i) == len(steps_d) == 1
        assert not steps_i[0].failed
    ui, ud = iterative.u.x.array, direct.u.x.array
    # Newton stops at rtol 1e-9 of the first residual; the Krylov tolerance (1e-6) enters the
    # state at about 1e-6 of its last correction: 1e-6 of the state's size bounds both by far.
    scale = beam.comm.allreduce(float(np.max(np.abs(ud), initial=0.0)), op=MPI.MAX)
    diff = beam.comm.allreduce(float(np.max(np.abs(ui - ud), initial=0.0)), op=MPI.MAX)
    assert scale > 0
    assert diff <= 1e-6 * scale, (case, diff, scale)
    # The clamp holds exactly on both paths (the defect let the iterative path move it).
    clamped = problem_dofs(iterative)
    assert np.all(ui[clamped] == 0.0)


def problem_dofs(problem) -> np.ndarray:
    """Local (unrolled) dof indices of the problem's Dirichlet conditions."""
    out = []
    for bc in problem.bcs:
        idx, first_ghost = bc.dof_indices()
        out.append(np.asarray(idx[:first_ghost]))
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int32)


def test_degree_thresholds():
    """P2 and P3 go iterative (the p-multigrid) from 10k unknowns, P4 from 20k; P5 keeps LU to 150k."""
    from dolfinx import mesh as dmesh

    from hyperfem.solver.linear import DIRECT_THRESHOLD, HIGH_ORDER_DIRECT_THRESHOLDS, direct_threshold

    def kind(cells, degree):
        box = dmesh.create_box(MPI.COMM_WORLD, [[0.0, 0.0, 0.0], [10.0, 4.0, 4.0]], cells)
        domain = hf.Domain.from_locators(box, {"clamped": lambda x: np.isclose(x[0], 0.0)})
        problem = hf.HyperelasticProblem(domain, _neo_hookean, degree=degree, bcs=[hf.Clamp("clamped")])
        ksp_type = choose_linear_solver(problem).options.get("ksp_type")
        return problem.V.dofmap.index_map.size_global * 3, ksp_type, problem

    n2, k2, _ = kind([14, 6, 6], 2)  # 14.7k unknowns
    n3, k3, p3 = kind([8, 4, 4], 3)  # 12.7k
    n4, k4, _ = kind([6, 3, 3], 4)  # 12.7k
    m4, j4, _ = kind([8, 4, 4], 4)  # 28.6k
    n5, k5, _ = kind([6, 3, 3], 5)  # 23.8k
    assert DIRECT_THRESHOLD < n2 and k2 == "cg"
    assert HIGH_ORDER_DIRECT_THRESHOLDS[3] < n3 and k3 == "cg"
    assert describe(choose_linear_solver(p3).options) == "cg+pmg"
    assert DIRECT_THRESHOLD < n4 < HIGH_ORDER_DIRECT_THRESHOLDS[4] and k4 == "preonly"
    assert HIGH_ORDER_DIRECT_THRESHOLDS[4] < m4 < 50_000 and j4 == "cg"  # LU to 50k before the p-multigrid
    assert HIGH_ORDER_DIRECT_THRESHOLDS[4] < n5 < HIGH_ORDER_DIRECT_THRESHOLDS[5] and k5 == "preonly"
    assert [direct_threshold(d) for d in (1, 2, 3)] == [DIRECT_THRESHOLD] * 3
    assert direct_threshold(5) == direct_threshold(7) > direct_threshold(4) > direct_threshold(3)
    # An explicit threshold still wins (P3 below it: LU).
    assert choose_linear_solver(p3, threshold=n3 + 1).options.get("ksp_type") == "preonly"
