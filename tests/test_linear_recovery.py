"""A Newton direction whose Krylov solve fails is recovered, not the end of the load step.

A tangent that stops CG (indefinite: an exact contact Hessian, strongly
compressed cells; or the iteration limit) is solved again with MUMPS up to
``DIRECT_FALLBACK_LIMIT`` unknowns (``NewtonSolver._recover_direction``).
Here a Krylov method that can never converge (two Jacobi-CG iterations)
stands in for the failing solve: the fallback must give the LU answer, and
without it the solve must fail as a linear-solve failure, saying which.
"""

from __future__ import annotations

import numpy as np
import pytest

from mpi4py import MPI

import hyperfem as hf
import hyperfem.solver.newton as newton
from hyperfem.simulation import Simulation
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube

PARAMS = hf.materials.LameParameters(mu=1.0, lmbda=2.0)
FAILING_KRYLOV = {"ksp_type": "cg", "pc_type": "jacobi", "ksp_max_it": 2, "snes_rtol": 1e-10}


def _solve(options: dict) -> tuple[hf.NewtonSolver, hf.SolveRecord, np.ndarray]:
    problem = hf.HyperelasticProblem(
        unit_cube(3), lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=uniaxial_rollers(1.3)
    )
    problem.set_time(1.0)
    solver = hf.NewtonSolver(problem, options)
    record = solver.solve()
    return solver, record, problem.u.x.array[: problem.u.function_space.dofmap.index_map.size_local * 3].copy()


def test_failed_krylov_solves_fall_back_to_lu_and_give_its_answer():
    _, reference, u_lu = _solve({"snes_rtol": 1e-10})
    solver, record, u = _solve(FAILING_KRYLOV)
    assert reference.converged and record.converged, record.message
    assert solver.direct_fallbacks == record.iterations > 0  # every direction came from the fallback
    assert np.abs(u - u_lu).max() < 1e-8 * np.abs(u_lu).max()  # both converged to snes_rtol 1e-10


def test_without_the_fallback_the_solve_fails_as_a_linear_solve(monkeypatch):
    monkeypatch.setattr(newton, "DIRECT_FALLBACK_LIMIT", 0)
    solver, record, _ = _solve(FAILING_KRYLOV)
    assert not record.converged
    assert record.reason_name == "DIVERGED_LINEAR_SOLVE"
    assert "linear solve failed (KSP reason -3)" in record.message  # KSP_DIVERGED_ITS
    assert solver.direct_fallbacks == 0


@pytest.mark.parametrize("limit", [0, newton.DIRECT_FALLBACK_LIMIT])
def test_a_stepper_run_cuts_back_or_goes_on(monkeypatch, limit):
    """In a stepped run the failure is an ordinary failed attempt (cut back, then the minimum step)."""
    monkeypatch.setattr(newton, "DIRECT_FALLBACK_LIMIT", limit)
    problem = hf.HyperelasticProblem(
        unit_cube(2), lambda F: hf.materials.neo_hookean(F, PARAMS), bcs=uniaxial_rollers(1.2)
    )
    solver = hf.NewtonSolver(problem, FAILING_KRYLOV)
    run = Simulation(problem, solver, hf.StepPolicy(increment=0.5, min_increment=0.1), [], name="recovery")
    if limit:
        assert run.run()["completed"]
    else:
        with pytest.raises(hf.ConvergenceError, match=r"linear solve failed \(KSP reason -3\)"):
            run.run()


def test_a_user_preconditioner_drops_the_linear_solvers_own_options():
    """pc_type jacobi over the direct default: no unused pc_factor_mat_solver_type left in PETSc's database."""
    from hyperfem.solver.linear import DIRECT
    from hyperfem.solver.options import merge_options

    merged = merge_options(True, DIRECT, FAILING_KRYLOV)
    assert merged["pc_type"] == "jacobi" and not any(k.startswith("pc_factor") for k in merged)
    kept = merge_options(True, DIRECT, {"ksp_type": "preonly", "pc_type": DIRECT["pc_type"]})
    assert kept["pc_factor_mat_solver_type"] == DIRECT["pc_factor_mat_solver_type"]
    amg = {"ksp_type": "cg", "pc_type": "gamg", "pc_gamg_threshold": 0.02}
    lu_over_amg = merge_options(True, amg, {"pc_type": "lu"})
    assert lu_over_amg["pc_factor_mat_solver_type"] == "mumps" and "pc_gamg_threshold" not in lu_over_amg


def test_a_user_preconditioner_of_one_split_drops_only_that_splits_options():
    """fieldsplit_u_pc_type gamg over the p-multigrid: the u block's own options go (GAMG would read its
    ``mg_levels`` ones), the other split's and the outer ones stay; an LU of one split gets MUMPS and keeps the
    outer lag."""
    from hyperfem.solver.linear import MIXED_ITERATIVE
    from hyperfem.solver.options import merge_options

    merged = merge_options(True, MIXED_ITERATIVE, {"fieldsplit_u_pc_type": "gamg"})
    assert merged["fieldsplit_u_pc_type"] == "gamg"
    assert not [k for k in merged if k.startswith(("fieldsplit_u_mg_", "fieldsplit_u_pc_python"))]
    assert merged["fieldsplit_u_ksp_type"] == "preonly" and merged["fieldsplit_p_pc_type"] == "lu"
    assert merged["pc_type"] == "fieldsplit" and merged["snes_lag_preconditioner"] == 3
    lu = merge_options(True, MIXED_ITERATIVE, {"fieldsplit_u_pc_type": "lu"})
    assert lu["fieldsplit_u_pc_factor_mat_solver_type"] == "mumps" and lu["snes_lag_preconditioner"] == 3
    same = merge_options(True, MIXED_ITERATIVE, {"fieldsplit_u_pc_type": "python"})
    assert same == merge_options(True, MIXED_ITERATIVE, None)


def test_a_user_factorisation_is_not_lagged_like_the_amg_it_replaces():
    """pc_type lu over the iterative path: no snes_lag_preconditioner left from the AMG (a chord method).

    The user's own lag is kept. End to end: the bend above the iterative threshold with the user's
    LU takes as many Newton iterations as with the direct linear solver forced (one more allowed: the
    two factorise BAIJ and AIJ matrices, equal to round-off).
    """
    from hyperfem.solver.linear import DIRECT, SYMMETRIC_ITERATIVE, choose_linear_solver
    from hyperfem.solver.options import merge_options

    amg = {**SYMMETRIC_ITERATIVE, "snes_lag_preconditioner": 5}
    assert "snes_lag_preconditioner" not in merge_options(True, amg, {"pc_type": "lu"})
    assert merge_options(True, amg, {"pc_type": "lu", "snes_lag_preconditioner": 3})["snes_lag_preconditioner"] == 3
    assert merge_options(True, amg, {"pc_type": "jacobi"})["snes_lag_preconditioner"] == 5
    preonly = merge_options(True, amg, dict(DIRECT))  # no unused Krylov tolerances in PETSc's database
    assert preonly["ksp_type"] == "preonly" and not {"ksp_rtol", "ksp_atol", "ksp_max_it"} & set(preonly)

    from hyperfem.cases import CantileverSpec, bend_load

    domain = hf.beam_mesh(h=1.0, comm=MPI.COMM_WORLD)
    params = CantileverSpec().lame
    counts = []
    for forced in ("user", "direct"):
        problem = hf.HyperelasticProblem(
            domain, lambda F: hf.materials.neo_hookean(F, params), degree=2, bcs=[hf.Clamp("clamped")],
            loads=[bend_load()],
        )
        if forced == "user":
            solver = hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, threshold=0),
                                     petsc_options=dict(DIRECT))
            assert "snes_lag_preconditioner" not in solver.options
        else:
            solver = hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, threshold=2**62))
        problem.set_time(1.0)
        counts.append(solver.solve(raise_on_failure=True).iterations)
    assert counts[0] <= counts[1] + 1  # lagged by 5 it took 4x as many on the benchmark's bend



STALE_EXACT = {"ksp_type": "cg", "pc_type": "lu", "ksp_max_it": 2, "snes_lag_preconditioner": 100, "snes_rtol": 1e-10}
"""CG with an exact factorisation that is lagged: built at the first Newton iteration, too old at the next ones."""


def _bend(options: dict, blocked: bool = False) -> tuple[hf.NewtonSolver, hf.SolveRecord, np.ndarray]:
    """The cantilever bend on ``beam_h2.msh``, full load in one Newton solve (the cube's uniaxial stretch is
    homogeneous: one CG iteration solves it on any tangent); ``blocked``: on the iterative path's blocked tangent,
    whose AIJ copy preconditions."""
    from pathlib import Path

    from hyperfem.cases import CantileverSpec, bend_load
    from hyperfem.solver.linear import choose_linear_solver

    domain = hf.read_mesh(Path(__file__).resolve().parent.parent / "meshes" / "beam_h2.msh")
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params),
                                     bcs=[hf.Clamp("clamped")], loads=[bend_load()])
    problem.set_time(1.0)
    linear = choose_linear_solver(problem, threshold=0) if blocked else None
    solver = hf.NewtonSolver(problem, options, linear_solver=linear)
    record = solver.solve()
    return solver, record, problem.u.x.array[: problem.u.function_space.dofmap.index_map.size_local * 3].copy()


@pytest.mark.parametrize(("limit", "blocked"), [(0, False), (newton.DIRECT_FALLBACK_LIMIT, False), (0, True)])
def test_a_lagged_preconditioner_that_fails_is_rebuilt_before_any_fallback(monkeypatch, limit, blocked):
    """A Krylov solve that fails with a lagged preconditioner (``snes_lag_preconditioner``, here an LU of the first
    tangent: 2 CG iterations do not reach the tolerance on the later ones) is solved again with the preconditioner
    rebuilt on the current tangent, not by MUMPS: the LU answer, no fallback, with or without the fallback allowed.
    On the blocked tangent the rebuilt preconditioner reads the AIJ copy of the current tangent (a stale copy
    failed again)."""
    monkeypatch.setattr(newton, "DIRECT_FALLBACK_LIMIT", limit)
    _, reference, u_lu = _bend({"snes_rtol": 1e-10})
    options = {**STALE_EXACT, "pc_factor_mat_solver_type": "mumps"}
    solver, record, u = _bend(options, blocked)
    assert reference.converged and record.converged, record.message
    assert solver.preconditioner_rebuilds > 0 and solver.direct_fallbacks == 0
    assert np.abs(u - u_lu).max() < 1e-8 * np.abs(u_lu).max()


def test_a_lagged_preconditioner_that_fails_a_lift_is_rebuilt_before_any_fallback():
    """The predictor's lift at the start of a step solves with the preconditioner as SNES left it; lagged, it is
    older than the lift's tangent. Here the beam's end is pulled down in 2 steps on the iterative path (CG + GAMG)
    and the material made 10^3 times stiffer between them, the hierarchy of the first step kept for reuse (as SNES
    does on the iterations it lags): its Chebyshev bounds no longer fit and the lift's Krylov solve fails. It is
    solved again with the preconditioner rebuilt, not by LU, and the run gives the LU answer."""
    from pathlib import Path

    from dolfinx import fem

    from hyperfem.cases import CantileverSpec
    from hyperfem.solver.linear import choose_linear_solver

    def run(iterative: bool) -> tuple[hf.NewtonSolver, np.ndarray]:
        domain = hf.read_mesh(Path(__file__).resolve().parent.parent / "meshes" / "beam_h2.msh")
        params = CantileverSpec().lame
        stiffness = fem.Constant(domain.mesh, 1.0)
        bcs = [hf.Clamp("clamped"), hf.PrescribedDisplacement("free_end", [0.0, -1.0, 0.0])]
        problem = hf.HyperelasticProblem(domain, lambda F: stiffness * hf.materials.neo_hookean(F, params), bcs=bcs)
        linear = choose_linear_solver(problem, threshold=0) if iterative else None
        solver = hf.NewtonSolver(problem, {"snes_rtol": 1e-10}, linear_solver=linear)
        problem.set_time(0.5)
        assert solver.solve().converged
        stiffness.value = 1e3
        assert not iterative or solver._lag.reused  # SNES kept the hierarchy of an earlier tangent (lag 10)
        solver.snes.getKSP().getPC().setReusePreconditioner(True)
        problem.set_time(1.0)
        assert solver.solve().converged
        return solver, problem.u.x.array[: problem.u.function_space.dofmap.index_map.size_local * 3].copy()

    _, u_lu = run(iterative=False)
    solver, u = run(iterative=True)
    predictor = solver._boundary_predictor
    assert predictor.preconditioner_rebuilds == 1 and predictor.direct_fallbacks == 0
    assert np.abs(u - u_lu).max() < 1e-8 * np.abs(u_lu).max()
