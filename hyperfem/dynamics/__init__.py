"""Dynamics: implicit (incremental potentials), semi-implicit and explicit stepping, damping, mass, diagnostics.

Time-integration concepts only; the reference set-ups (the dynamic
cantilever, beam theory) live in :mod:`hyperfem.cases`, the time profiles and
prescribed motions in :mod:`hyperfem.loading` (:class:`Steady`, :class:`Ramp`,
:func:`rotating_surface`, ... are re-exported here for dynamic set-ups). Any problem that
meets :class:`~hyperfem.problem.protocol.SolidProblem` (displacement or
three-field) can be integrated in time.

>>> from mpi4py import MPI
>>> import hyperfem as hf
>>> from hyperfem import dynamics as dyn
>>> domain = hf.beam_mesh(h=2.0)
>>> params = hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3)
>>> base = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params),
...     bcs=[hf.Clamp("clamped")],
...     loads=[hf.DeadTraction("free_end", (0, -5e3, 0), profile=dyn.Steady())])
>>> problem = dyn.IncrementalProblem(base, dyn.Newmark(), dyn.MassDensity(1000.0))
>>> history = dyn.integrate(problem, hf.NewtonSolver(problem), dyn.TimeStepping(dt=0.05, t_end=0.1))
"""

from hyperfem.dynamics.damping import RayleighDamping, reference_stiffness_form, viscous_damping
from hyperfem.dynamics.diagnostics import Diagnostics
from hyperfem.dynamics.explicit import ExplicitDynamics, ExplicitStage, integrate_explicit
from hyperfem.dynamics.incremental import DisplacementBlock, DynamicState, IncrementalProblem
from hyperfem.dynamics.integrators import BackwardEuler, GeneralizedAlpha, Newmark, QuasiStatic, TimeIntegrator
from hyperfem.dynamics.mass import MassDensity, lumped_mass, total_mass
from hyperfem.dynamics.realtime import RealtimeConfig, RealtimeStep, RealtimeStepper, RealtimeSummary
from hyperfem.dynamics.semi_implicit import (
    SemiImplicitStage,
    integrate_semi_implicit,
    linearization_residual,
    semi_implicit_solver,
)
from hyperfem.dynamics.stability import StableStep, inscribed_diameters, stable_time_step, wave_speed
from hyperfem.loading import Ramp, RigidRotation, Steady, rotating_surface, rotation_matrix
from hyperfem.solver.stepping import TimeStepping, integrate

__all__ = [
    "BackwardEuler",
    "Diagnostics",
    "DisplacementBlock",
    "DynamicState",
    "ExplicitDynamics",
    "ExplicitStage",
    "GeneralizedAlpha",
    "IncrementalProblem",
    "MassDensity",
    "Newmark",
    "QuasiStatic",
    "Ramp",
    "RayleighDamping",
    "RealtimeConfig",
    "RealtimeStep",
    "RealtimeStepper",
    "RealtimeSummary",
    "RigidRotation",
    "SemiImplicitStage",
    "StableStep",
    "Steady",
    "TimeIntegrator",
    "TimeStepping",
    "inscribed_diameters",
    "integrate",
    "integrate_explicit",
    "integrate_semi_implicit",
    "linearization_residual",
    "lumped_mass",
    "reference_stiffness_form",
    "rotating_surface",
    "rotation_matrix",
    "semi_implicit_solver",
    "stable_time_step",
    "total_mass",
    "viscous_damping",
    "wave_speed",
]
