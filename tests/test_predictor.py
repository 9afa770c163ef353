"""The boundary-increment predictor of :class:`~hyperfem.solver.NewtonSolver`.

Displacement-driven loading used to move only the boundary nodes before
Newton started; the first layer of cells was squeezed and each step crawled
out of that state: a nearly incompressible cube (K/μ = 10⁴, P1, 4³ cells)
stretched to λ = 2 took 129 load steps and 1,255 Newton iterations. The
predictor solves K(u_n) δu = 0 with δu = g_{n+1} − u_n on the Dirichlet dofs
(a lifted condition) and starts Newton from u_n + δu. Measured with it:
3 load steps, 10 Newton iterations (λ = 2), 3 and 9 (λ = 0.5), on 2³, 4³
and 8³ meshes alike.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest


import hyperfem as hf
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube
from hyperfem.cases import CantileverSpec
from hyperfem.kinematics import isochoric_invariants
from hyperfem.loading import Ramp, rotating_surface
from hyperfem.problem import SplitEnergy, solid_problem

MESHES = Path(__file__).resolve().parent.parent / "meshes"


_cube = unit_cube
_rollers = uniaxial_rollers


@pytest.mark.parametrize("stretch", [2.0, 0.5])
def test_displacement_driven_nearly_incompressible_stretch_is_fast(stretch):
    """P1, K/μ = 10⁴: at most 8 load steps and 60 Newton iterations (was 129 and 1,255)."""
    domain = _cube(4)
    material = SplitEnergy(lambda F: 0.5 * (isochoric_invariants(F)[0] - 3.0), 1e4)
    problem = solid_problem(domain, material, bcs=_rollers(stretch), formulation="displacement")
    steps = hf.solve_quasistatic(hf.NewtonSolver(problem), stepping=hf.LoadStepping(initial_increment=0.25))
    assert len(steps) <= 8
    assert sum(s.solve.iterations for s in steps) <= 60
    assert all(s.solve.predictor for s in steps)
    # Homogeneous: u = (λ - 1) x e_x + (λ_t - 1)(y e_y + z e_z), λ_t -> 1/sqrt(λ) as K/μ grows.
    x = problem.V.tabulate_dof_coordinates()
    u = problem.u.x.array.reshape(-1, 3)
    lateral = 1.0 / math.sqrt(stretch) - 1.0
    np.testing.assert_allclose(u[:, 0], (stretch - 1.0) * x[:, 0], atol=1e-9)
    np.testing.assert_allclose(u[:, 1], lateral * x[:, 1], atol=5e-3 * abs(lateral))
    np.testing.assert_allclose(u[:, 2], lateral * x[:, 2], atol=5e-3 * abs(lateral))


def test_predictor_solves_a_linear_problem():
    """For a linear material the predictor is the solution: Newton has nothing left to do."""
    domain = _cube(2)
    params = hf.materials.LameParameters.from_youngs(1.0, 0.3)
    problem = hf.HyperelasticProblem(
        domain, lambda F: hf.materials.linear_elastic(F, params), bcs=_rollers(1.1)
    )
    solver = hf.NewtonSolver(problem)
    problem.set_time(1.0)
    rec = solver.solve(raise_on_failure=True)
    assert rec.predictor
    assert rec.iterations <= 2  # 0 when the predicted residual is below atol, else one step to the floor
    off = hf.HyperelasticProblem(domain, lambda F: hf.materials.linear_elastic(F, params), bcs=_rollers(1.1))
    off.set_time(1.0)
    hf.NewtonSolver(off, predictor=False).solve(raise_on_failure=True)
    np.testing.assert_allclose(problem.u.x.array, off.u.x.array, atol=1e-12)


def test_predictor_only_when_the_boundary_moves():
    domain = hf.read_mesh(MESHES / "beam_h2.msh")
    params = CantileverSpec().lame
    problem = hf.HyperelasticProblem(
        domain,
        lambda F: hf.materials.neo_hookean(F, params),
        bcs=[hf.Clamp("clamped")],
        loads=[hf.DeadTraction("free_end", (0.0, -5e3, 0.0))],
    )
    steps = hf.solve_quasistatic(hf.NewtonSolver(problem))
    assert not any(s.solve.predictor for s in steps)


def _half_turn(predictor: bool):
    domain = hf.read_mesh(MESHES / "beam_h2.msh")
    params = CantileverSpec().lame
    turn = rotating_surface("free_end", (1.0, 0.0, 0.0), Ramp(1.0, final=math.pi), (5.0, 0.0, 0.0))
    bcs = [hf.Clamp("clamped"), turn]
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params), bcs=bcs)
    steps = hf.solve_quasistatic(
        hf.NewtonSolver(problem, predictor=predictor), stepping=hf.LoadStepping(initial_increment=0.25)
    )
    return problem.u.x.array.copy(), sum(s.solve.iterations + sum(f.iterations for f in s.failed) for s in steps)


def test_prescribed_rotation_with_predictor():
    """Static BC-twist (free end turned by π): same state, far fewer iterations (measured 18 vs 34)."""
    u_on, its_on = _half_turn(True)
    u_off, its_off = _half_turn(False)
    np.testing.assert_allclose(u_on, u_off, atol=1e-8)
    assert its_on < its_off


def test_predictor_is_exact_for_a_linear_problem_at_every_step():
    """The predictor's lifting reads the state's ghosts: from the second load step on, on any
    number of ranks, a linear problem starts Newton at its solution (on 2 ranks the copy of the
    owned entries left the ghosts one step behind and the start residual was O(0.1))."""
    domain = _cube(3)
    params = hf.materials.LameParameters.from_youngs(1.0, 0.3)
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.linear_elastic(F, params), bcs=_rollers(1.3))
    solver = hf.NewtonSolver(problem)
    starts = []
    for s in (0.25, 0.5, 0.75, 1.0):
        problem.set_time(s)
        rec = solver.solve(raise_on_failure=True)
        assert rec.predictor
        starts.append(rec.residual_norms[0])
    # The residual of a unit-modulus cube stretched by 0.075 per step is O(1e-2) before the
    # predictor; after it, round-off (1e-15 here). 1e-9 separates the two by orders of magnitude.
    assert max(starts) < 1e-9, starts


def test_a_solve_refused_at_its_start_reports_no_iterations():
    """A solve refused before Newton (start state inverted) must not report the previous solve's counts."""
    domain = _cube(2)
    params = hf.materials.LameParameters.from_youngs(1.0, 0.3)
    problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params), bcs=_rollers(1.2))
    solver = hf.NewtonSolver(problem, predictor=False)
    problem.set_time(1.0)
    first = solver.solve(raise_on_failure=True)
    assert first.iterations > 0
    # Fold the body through itself: every x-coordinate mirrored, J < 0 everywhere.
    x = problem.V.tabulate_dof_coordinates()[:, 0]
    u = problem.u.x.array.reshape(-1, 3)
    u[:, 0] = -2.0 * x * 1.5
    problem.u.x.scatter_forward()
    rec = solver.solve()
    assert not rec.converged
    assert "start state" in rec.message
    assert rec.iterations == 0 and rec.linear_iterations == 0 and rec.ksp_reason == 0
    assert rec.residual_norms == []
