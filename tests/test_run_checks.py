"""Inputs that used to run into the wrong error, and a result that needed a word.

* ``min_jacobian = 5`` was accepted and failed as a stepping error ("start
  state has J <= 5"); it is refused at construction.
* ``t_end = -1`` through the API was refused as "got dt = -0.01".
* A load a million times the bend case "converged" to a 123 km deflection
  without a word: a displacement above ten times the body's size warns, once.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

import hyperfem as hf
from hyperfem import dynamics as dyn
from hyperfem.cases.uniaxial import uniaxial_rollers, unit_cube
from hyperfem.errors import ParameterError
from hyperfem.simulation import Probe, Simulation
from hyperfem.simulation.runner import LargeDisplacementWarning
from hyperfem.solver.stepping import TimeStepping, integrate

PARAMS = hf.materials.LameParameters.from_youngs(1.0, 0.3)


def _psi(F):
    return hf.materials.neo_hookean(F, PARAMS)


@pytest.mark.parametrize("value", [5.0, 1.0, -0.1])
def test_min_jacobian_outside_0_1_is_refused(value):
    problem = hf.HyperelasticProblem(unit_cube(1), _psi, bcs=uniaxial_rollers(1.1))
    with pytest.raises(ParameterError, match=r"min_jacobian must be in \[0, 1\) .*got "):
        hf.NewtonSolver(problem, min_jacobian=value)


def test_a_time_integration_ending_before_its_start_is_refused():
    mesh = dmesh.create_box(MPI.COMM_WORLD, [[0, 0, 0], [1, 0.3, 0.3]], [4, 1, 1])
    domain = hf.Domain.from_locators(mesh, {"left": lambda x: np.isclose(x[0], 0.0)})
    base = hf.HyperelasticProblem(domain, _psi, bcs=[hf.Clamp("left")])
    problem = dyn.IncrementalProblem(base, dyn.Newmark(), dyn.MassDensity(1.0))
    with pytest.raises(ParameterError, match=r"integrate: t_end = -1 is not after the problem's time 0"):
        integrate(problem, hf.NewtonSolver(problem), TimeStepping(dt=0.01, t_end=-1.0))


@pytest.mark.parametrize("stretch, warned", [(30.0, True), (3.0, False)])
def test_a_displacement_far_beyond_the_body_warns_once(stretch, warned):
    """A unit cube pulled to 30 times its length: u = 29 > 10 x 1.73 (the cube's diagonal)."""
    problem = hf.HyperelasticProblem(unit_cube(2), _psi, bcs=uniaxial_rollers(stretch))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        summary = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(increment=0.25), [Probe([(1, 1, 1)])],
                             name="pull").run()
    assert summary["completed"]
    mine = [str(w.message) for w in caught if issubclass(w.category, LargeDisplacementWarning)]
    if not warned or MPI.COMM_WORLD.rank != 0:
        assert mine == []
        return
    assert len(mine) == 1  # once, at the first state beyond the bound
    assert mine[0].startswith("pull: the displacement reaches ")
    assert "times the body's size (1.73, the diagonal of its bounding box); check the loads" in mine[0]
