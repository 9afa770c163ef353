"""Issue 18: the optional contracts are declared as protocols, and a plain user energy still works.

The classes of the library meet the protocols that the solver, the dynamics and the
outputs branch on (:mod:`hyperfem.problem.protocol`); a callable ``psi(F)`` with no
extras is seen through :func:`hyperfem.problem.energy.as_energy` with neutral ones,
and an energy with only some extras keeps them.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from dolfinx import mesh as dmesh

import hyperfem as hf
from hyperfem import dynamics as dyn
from hyperfem.materials import LameParameters, neo_hookean, with_parameters
from hyperfem.materials.fixed_corotated import ARAP, FixedCorotated
from hyperfem.materials.corotational_linear import CorotationalLinear
from hyperfem.problem import SplitEnergy
from hyperfem.problem.energy import as_energy
from hyperfem.problem.mixed import MixedHyperelasticProblem
from hyperfem.problem.protocol import (
    CorrectedTangentProblem,
    EnergyProtocol,
    InvertibleProblem,
    MixedProblemProtocol,
    SolidProblem,
    StateHookedProblem,
    TimeStepProblem,
    TimeStepState,
)

PARAMS = LameParameters(mu=1.0, lmbda=2.0)
STRETCH = 0.05  # prescribed end displacement of the unit square


def _square(comm):
    mesh = dmesh.create_unit_square(comm, 4, 4, dmesh.CellType.triangle)
    return hf.Domain.from_locators(
        mesh, {"left": lambda x: np.isclose(x[0], 0.0), "right": lambda x: np.isclose(x[0], 1.0)}
    )


def _bcs():
    return [hf.Clamp("left"), hf.PrescribedDisplacement("right", (STRETCH, 0.0))]


def _solve(problem) -> np.ndarray:
    problem.set_time(1.0)  # the full prescribed stretch
    record = hf.NewtonSolver(problem).solve()
    assert record.converged
    return problem.u.x.array.copy()


def test_library_classes_meet_the_protocols(comm):
    domain = _square(comm)
    problem = hf.HyperelasticProblem(domain, with_parameters(neo_hookean, PARAMS), bcs=_bcs())
    for protocol in (SolidProblem, InvertibleProblem, StateHookedProblem, CorrectedTangentProblem):
        assert isinstance(problem, protocol)
    assert not isinstance(problem, MixedProblemProtocol)
    assert not isinstance(problem, TimeStepProblem)

    mixed = MixedHyperelasticProblem(domain, SplitEnergy(lambda F: neo_hookean(F, PARAMS), 1.0), bcs=_bcs())
    assert isinstance(mixed, MixedProblemProtocol) and mixed.saddle_point

    step = dyn.IncrementalProblem(problem, dyn.QuasiStatic())
    for protocol in (SolidProblem, TimeStepProblem, TimeStepState, InvertibleProblem, StateHookedProblem):
        assert isinstance(step, protocol)

    for energy in (FixedCorotated(PARAMS), ARAP(PARAMS.mu), CorotationalLinear(PARAMS)):
        assert isinstance(energy, EnergyProtocol)
        assert as_energy(energy) is energy


def test_plain_energy_gets_neutral_extras():
    def psi(F):
        return neo_hookean(F, PARAMS)

    assert not isinstance(psi, EnergyProtocol)
    energy = as_energy(psi)
    assert isinstance(energy, EnergyProtocol)
    assert energy.invertible is False
    assert energy.state_hooks == () and energy.updaters == ()
    assert energy.quadrature_rule_degree is None
    assert energy.tangent_correction(None) is None
    energy.bind(None, 2)  # a no-op
    # A known invertible law behind with_parameters keeps its flag.
    assert as_energy(with_parameters(hf.materials.robust_neo_hookean, PARAMS)).invertible is True


def test_minimal_user_energy_solves_like_the_library_one(comm):
    domain = _square(comm)
    plain = hf.HyperelasticProblem(domain, lambda F: neo_hookean(F, PARAMS), bcs=_bcs())
    library = hf.HyperelasticProblem(domain, with_parameters(neo_hookean, PARAMS), bcs=_bcs())
    assert plain.invertible is False and plain.state_hooks == () and plain.tangent_correction is None
    u_plain, u_library = _solve(plain), _solve(library)
    scale = comm.allreduce(float(np.max(np.abs(u_library))), op=MPI.MAX)
    error = comm.allreduce(float(np.max(np.abs(u_plain - u_library), initial=0.0)), op=MPI.MAX)
    assert scale > 0.5 * STRETCH
    assert error <= 1e-8 * scale


class _PartialEnergy:
    """A user energy with some extras only (``bind`` and ``state_hooks``)."""

    def __init__(self):
        self.bound: list[int] = []
        self.calls = 0
        self.state_hooks = (self._hook,)

    def _hook(self) -> None:
        self.calls += 1

    def bind(self, F, quadrature_degree: int) -> None:
        self.bound.append(quadrature_degree)

    def __call__(self, F):
        return neo_hookean(F, PARAMS)


def test_partial_user_energy_keeps_its_extras(comm):
    psi = _PartialEnergy()
    assert not isinstance(psi, EnergyProtocol)
    problem = hf.HyperelasticProblem(_square(comm), psi, bcs=_bcs())
    assert psi.bound == [problem.quadrature_degree]
    assert problem.state_hooks == (psi._hook,)
    assert problem.invertible is False and problem.tangent_correction is None
    solver = hf.NewtonSolver(problem)
    assert psi._hook in solver.state_hooks
    problem.set_time(1.0)
    assert solver.solve().converged
    assert psi.calls > 0


@pytest.mark.parametrize("dynamic", [False, True])
def test_simulation_kind_from_the_time_step_protocol(comm, dynamic):
    base = hf.HyperelasticProblem(_square(comm), with_parameters(neo_hookean, PARAMS), bcs=_bcs())
    problem = dyn.IncrementalProblem(base, dyn.QuasiStatic()) if dynamic else base
    sim = hf.Simulation(problem, hf.NewtonSolver(problem), hf.LoadStepping())
    assert sim.kind == ("dynamic" if dynamic else "quasi-static")
    assert sim.fields.base is base
    assert (sim.fields.velocity is problem.v) if dynamic else sim.fields.velocity is None
