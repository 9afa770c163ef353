r"""Semi-implicit time integration: one linearization of the implicit step per time step.

A time step of an :class:`~hyperfem.dynamics.IncrementalProblem` solves
:math:`R_\Delta(u_{n+1}) = 0` (backward Euler: seed 000 eq. 2.15, seed 003
§2). The *semi-implicit* (linearly implicit) scheme takes exactly one Newton
iteration from the predictor :math:`u^{(0)} = u_n + \Delta t\,v_n` with the
prescribed values of :math:`t_{n+1}` on the Dirichlet dofs,

.. math::
    K_\Delta(u^{(0)})\,\delta u = -R_\Delta(u^{(0)}),\qquad u_{n+1} = u^{(0)} + \delta u,

and accepts the result whether or not it meets the Newton tolerance; the
residual left, :math:`\|R_\Delta(u_{n+1})\|`, is recorded with every step
(:func:`linearization_residual`). For a linear material it is round-off (one
Newton iteration solves a linear step exactly), so SI-FEM then *is* the
implicit scheme; for large deformation it is the error of the linearization.
With backward Euler the scheme is first order and dissipative; with Newmark
it keeps Newmark's second order (the residual left is of higher order in
:math:`\Delta t`).

* SI-FEM: ``IncrementalProblem(base, BackwardEuler(), MassDensity(rho))``
  (consistent mass);
* L-FEM: the same with ``MassDensity(rho, lumped=True)``.

The step reuses the line-searched :class:`~hyperfem.solver.NewtonSolver`
(its assembly, linear solver and inversion pre-check) configured by
:func:`semi_implicit_solver`: ``snes_max_it = 1``, the ``basic`` (full-step)
line search, no energy line search, no boundary-increment predictor (that
would be a second linear solve). :class:`SemiImplicitStage` accepts the
iteration's ``DIVERGED_MAX_IT`` by design; a failed linear solve, a
non-finite residual or an inverted element still fail the step (and
:func:`~hyperfem.solver.stepping.run_steps` cuts it back).
:func:`integrate_semi_implicit` runs it as a
:class:`~hyperfem.simulation.Simulation` (with its outputs) with this stage::

    Simulation(problem, semi_implicit_solver(problem), stepping, outputs, stage=SemiImplicitStage).run()

Contact (``semi_implicit_solver(problem, external_energies=[contact])``):
the collision filter shortens the one Newton step as it does any Newton
step, so no step penetrates; but one linearization does not resolve the
barrier, and an impact is inelastic (a block dropped on a plane comes to
rest on it with its kinetic energy gone, where backward Euler with full
Newton solves bounces; ``tests/test_contact.py``).

Seed 003 uses "SI-FEM" for the scheme with the elastic forces explicit and a
consistent-mass velocity solve (its §5.5: "the coefficient matrix of the
velocity update is the mass matrix"); that scheme is
:class:`~hyperfem.dynamics.explicit.ExplicitDynamics` with a consistent
:class:`~hyperfem.dynamics.MassDensity`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any, cast

import numpy as np
from mpi4py import MPI  # noqa: F401  (before petsc4py)
from petsc4py import PETSc

from hyperfem.dynamics.incremental import IncrementalProblem
from hyperfem.errors import ParameterError
from hyperfem.solver.newton import NewtonSolver, SolveRecord
from hyperfem.simulation.outputs import OnStep
from hyperfem.simulation.runner import Simulation
from hyperfem.solver.stepping import DynamicStage, StepRecord, TimeStepping

__all__ = [
    "SEMI_IMPLICIT_OPTIONS",
    "SemiImplicitStage",
    "accept_linearization",
    "integrate_semi_implicit",
    "linearization_residual",
    "semi_implicit_solver",
]

SEMI_IMPLICIT_OPTIONS: dict[str, object] = {
    "snes_max_it": 1,
    "snes_linesearch_type": "basic",
    "snes_rtol": 1e-10,
    "snes_atol": 1e-12,
    "snes_stol": 0.0,
}
"""SNES options of the single iteration (the KSP/PC part is the solver's usual choice)."""

_MAX_IT = int(PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT)


def semi_implicit_solver(
    problem: IncrementalProblem, petsc_options: dict[str, Any] | None = None, **kwargs: Any
) -> NewtonSolver:
    """A :class:`~hyperfem.solver.NewtonSolver` that takes exactly one Newton iteration.

    Args:
        problem: The incremental problem (any integrator).
        petsc_options: Options merged over :data:`SEMI_IMPLICIT_OPTIONS`
            (e.g. a linear solver); ``snes_max_it`` must stay 1.
        **kwargs: Passed to :class:`~hyperfem.solver.NewtonSolver`; defaults
            ``energy_line_search=False``, ``predictor=False``.

    Raises:
        ParameterError: If the options ask for more than one iteration.
    """
    options = {**SEMI_IMPLICIT_OPTIONS, **(petsc_options or {})}
    if int(options["snes_max_it"]) != 1:
        raise ParameterError(
            f"semi_implicit_solver: a semi-implicit step is one Newton iteration, got snes_max_it = "
            f"{options['snes_max_it']!r}"
        )
    kwargs.setdefault("energy_line_search", False)
    kwargs.setdefault("predictor", False)
    return NewtonSolver(problem, options, **kwargs)


def linearization_residual(record: SolveRecord | StepRecord) -> tuple[float, float]:
    """Residual norm left after the step's (last) iteration: ``(absolute, relative to the step's start)``.

    Args:
        record: The solve record, or a step record (its last accepted solve).
    """
    solve = record.solve if isinstance(record, StepRecord) else record
    norms = solve.residual_norms
    if not norms:
        return float("nan"), float("nan")
    r0, r1 = float(norms[0]), float(norms[-1])
    return r1, (r1 / r0 if r0 > 0 else 0.0)


def accept_linearization(record: SolveRecord) -> SolveRecord:
    """The record of one semi-implicit iteration, accepted when it only missed the Newton tolerance.

    A converged record is returned as it is. ``DIVERGED_MAX_IT`` with a
    finite residual and a finite :math:`\\min J` becomes ``converged=True``
    (the reason stays ``DIVERGED_MAX_IT``, the message states the residual
    left); every other failure is returned unchanged.
    """
    if record.converged:
        return record
    r1, rel = linearization_residual(record)
    if record.reason != _MAX_IT or not np.isfinite(r1) or not np.isfinite(record.min_J) or record.message:
        return record
    return dataclasses.replace(
        record,
        converged=True,
        message=f"one linearization: residual {r1:.3g} left ({rel:.3g} of the step's initial residual)",
    )


class SemiImplicitStage(DynamicStage):
    """:class:`~hyperfem.solver.stepping.DynamicStage` that accepts the single iteration of a semi-implicit step.

    Args:
        problem: The incremental problem; its accepted state is the start.
        solver: A one-iteration solver (:func:`semi_implicit_solver`).

    Raises:
        ParameterError: If the solver takes more than one iteration.
    """

    def __init__(self, problem: IncrementalProblem, solver: NewtonSolver):
        max_it = cast("str | float", solver.options.get("snes_max_it", 0))  # an option value: a number or its text
        if int(max_it) != 1:
            raise ParameterError(
                "SemiImplicitStage: the solver must take exactly one Newton iteration (use semi_implicit_solver)"
            )
        super().__init__(problem, solver)

    def advance(self, t: float, dt: float) -> SolveRecord:
        """Prepare the step and take the one Newton iteration."""
        return accept_linearization(super().advance(t, dt))


def integrate_semi_implicit(
    problem: IncrementalProblem,
    solver: NewtonSolver,
    stepping: TimeStepping,
    on_step: Callable[[StepRecord], None] | None = None,
    outputs: Sequence = (),
) -> list[StepRecord]:
    """Advance ``problem`` to ``stepping.t_end`` with one linearization per step.

    ``Simulation(problem, solver, stepping, [*outputs, OnStep(on_step)], stage=SemiImplicitStage).run()``.

    Args:
        problem: The incremental problem (call its ``initial_acceleration`` first, as for
            :func:`~hyperfem.dynamics.integrate`).
        solver: From :func:`semi_implicit_solver`.
        stepping: Step control.
        on_step: Called after every accepted step (after ``outputs``); :func:`linearization_residual`
            of its record is the residual left.
        outputs: Observers of every accepted step (:mod:`hyperfem.simulation.outputs`).

    Returns:
        The accepted steps.

    Raises:
        ParameterError: If ``solver`` takes more than one iteration.
        ConvergenceError: When failed linear solves or inverted elements cut the step below ``dt_min``.
    """
    observers = [*outputs, *([OnStep(on_step)] if on_step is not None else [])]
    sim = Simulation(problem, solver, stepping, observers, stage=SemiImplicitStage, name="integrate_semi_implicit")
    sim.run()
    return sim.steps
