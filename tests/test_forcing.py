"""The Krylov tolerance of the Newton step predicted to be the last (:mod:`hyperfem.solver.forcing`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

import hyperfem as hf
from hyperfem.cases import TEST_POINT, CantileverSpec, bend_load
from hyperfem.io import PointProbe
from hyperfem.solver.forcing import DEEPEST, MARGIN, FinalStepForcing
from hyperfem.solver.linear import choose_linear_solver


MESHES = Path(__file__).resolve().parents[1] / "meshes"


def _snes(ksp_type: str = "cg", rtol: float = 1e-6) -> PETSc.SNES:
    snes = PETSc.SNES().create(MPI.COMM_SELF)
    snes.setTolerances(rtol=1e-9, atol=1e-13)
    ksp = snes.getKSP()
    ksp.setType(ksp_type)
    ksp.setTolerances(rtol=rtol)
    return snes


# The residual norms of the 212k-unknown bend (benchmarks/scale.py --sizes 32), whose fifth iteration on two ranks
# this forcing removes.
BEND = [2.460971946408e03, 3.768712565415e04, 6.791083474688e02, 3.555824428620e-01]


def test_the_predicted_last_step_is_solved_tighter_and_the_tolerance_restored():
    snes = _snes()
    forcing = FinalStepForcing(snes)
    rtols = []
    for it, norm in enumerate(BEND):
        forcing(snes, it, norm, 0)
        rtols.append(snes.getKSP().getTolerances()[0])
    # Not yet converging (the residual grew), then not yet quadratic enough: the configured tolerance.
    assert rtols[:3] == [1e-6, 1e-6, 1e-6]
    target = 1e-9 * BEND[0]
    assert rtols[3] == pytest.approx(MARGIN * target / BEND[3], rel=1e-12)
    assert forcing.tightened == 1
    forcing(snes, 4, 6.9e-7, int(PETSc.SNES.ConvergedReason.CONVERGED_FNORM_RELATIVE))
    assert snes.getKSP().getTolerances()[0] == 1e-6  # the end of the solve restores it
    forcing(snes, 0, 1.0, 0)  # and so does the start of the next one
    assert snes.getKSP().getTolerances()[0] == 1e-6


def test_the_tightening_is_bounded_and_leaves_direct_solvers_alone():
    snes = _snes()
    forcing = FinalStepForcing(snes)
    for it, norm in enumerate([1.0, 1e4, 0.1]):  # target 1e-9: would ask for 1e-10
        forcing(snes, it, norm, 0)
    assert snes.getKSP().getTolerances()[0] == pytest.approx(DEEPEST)
    forcing.restore()
    loose = _snes(rtol=1e-4)  # the floor does not rise with the configured tolerance
    forcing = FinalStepForcing(loose)
    for it, norm in enumerate([1.0, 1e4, 0.1]):
        forcing(loose, it, norm, 0)
    assert loose.getKSP().getTolerances()[0] == pytest.approx(DEEPEST)
    forcing.restore()
    direct = _snes("preonly")
    forcing = FinalStepForcing(direct)
    for it, norm in enumerate(BEND):
        forcing(direct, it, norm, 0)
    assert direct.getKSP().getTolerances()[0] == 1e-6 and forcing.tightened == 0


def test_a_newton_solve_restores_the_configured_krylov_tolerance():
    """A bend on the iterative path: LU's answer, and the KSP keeps its configured tolerance between solves."""
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(
        hf.read_mesh(MESHES / "beam_h2.msh"),
        lambda F: hf.materials.neo_hookean(F, params),
        bcs=[hf.Clamp("clamped")],
        loads=[bend_load()],
    )
    linear = choose_linear_solver(problem, threshold=0)
    solver = hf.NewtonSolver(problem, linear_solver=linear)
    steps = hf.solve_quasistatic(solver)
    assert all(s.solve.converged for s in steps)
    assert solver.snes.getKSP().getTolerances()[0] == pytest.approx(float(linear.options["ksp_rtol"]), rel=1e-15)
    iterative = PointProbe(problem.domain.mesh, [TEST_POINT])(problem.u)[0]
    problem.u.x.array[:] = 0.0
    problem.set_time(0.0)
    hf.solve_quasistatic(hf.NewtonSolver(problem, linear_solver=choose_linear_solver(problem, threshold=10**12)))
    direct = PointProbe(problem.domain.mesh, [TEST_POINT])(problem.u)[0]
    np.testing.assert_allclose(iterative, direct, rtol=1e-8, atol=1e-10)
