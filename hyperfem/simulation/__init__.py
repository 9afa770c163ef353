"""Runs: a problem, its solver, a step policy, and outputs that observe every accepted step.

>>> from mpi4py import MPI
>>> import hyperfem as hf
>>> from hyperfem.simulation import Checkpoint, CSVLog, FieldOutput, JSONSummary, Probe, Reactions, Simulation
>>> domain = hf.beam_mesh(h=2.0)
>>> params = hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3)
>>> psi = lambda F: hf.materials.neo_hookean(F, params)
>>> problem = hf.HyperelasticProblem(domain, psi,
...     bcs=[hf.Clamp("clamped")], loads=[hf.DeadTraction("free_end", (0, -5e3, 0))])
>>> outputs = [Probe([(4.5, 1.5, 1.5)]), Reactions(), CSVLog("output/bend.csv"),
...     FieldOutput("output", psi, name="bend"), JSONSummary("output/bend.json"),
...     Checkpoint("output/bend.checkpoint", every=5)]
>>> sim = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(end=1.0, increment=0.5), outputs, name="bend")
>>> summary = sim.run()            # or sim.run(restart="output/bend.checkpoint") after a kill

The same :class:`Simulation` runs an :class:`~hyperfem.dynamics.IncrementalProblem`
under a :class:`~hyperfem.dynamics.TimeStepping`.

What each output writes is on disk after every step (a killed run keeps every
completed step). Modules: :mod:`~hyperfem.simulation.outputs` (files),
:mod:`~hyperfem.simulation.measures` (probes, boundary averages, cell fields),
:mod:`~hyperfem.simulation.reactions` (reaction forces and moments of every
Dirichlet boundary), :mod:`~hyperfem.simulation.fields` (stress, von Mises,
J, fibre stretch, activation in VTX or XDMF), :mod:`~hyperfem.simulation.checkpoint`
(checkpoint/restart), :mod:`~hyperfem.simulation.plots` (PNG plots of a run's files).
"""

from hyperfem.simulation.measures import (
    BoundaryAverage,
    CellFunctions,
    CellVTX,
    Probe,
    RadialBulge,
    Reaction,
    cauchy_stress,
)
from hyperfem.simulation.outputs import (
    VTX,
    XDMF,
    ConvergenceLog,
    CSVLog,
    Derived,
    JSONSummary,
    OnStep,
    Output,
    Progress,
    Quantity,
    Recorder,
    continuation_path,
    format_summary,
    read_convergence,
)
from hyperfem.simulation.reactions import DirichletReactions, ReactionResult, Reactions
from hyperfem.simulation.fields import FieldOutput, cell_field_expressions, von_mises
from hyperfem.simulation.render import Render, Surface, boundary_surface, render_png
from hyperfem.simulation.checkpoint import Checkpoint, CheckpointError, StepperState
from hyperfem.simulation.runner import Simulation, StateFunctions
from hyperfem.simulation.stability import Stability, UnstableStateWarning

__all__ = [
    "VTX",
    "XDMF",
    "BoundaryAverage",
    "CSVLog",
    "CellFunctions",
    "CellVTX",
    "Checkpoint",
    "CheckpointError",
    "ConvergenceLog",
    "Derived",
    "DirichletReactions",
    "FieldOutput",
    "JSONSummary",
    "OnStep",
    "Output",
    "Probe",
    "Progress",
    "Quantity",
    "RadialBulge",
    "Reaction",
    "ReactionResult",
    "Reactions",
    "Recorder",
    "Render",
    "Simulation",
    "Stability",
    "StateFunctions",
    "StepperState",
    "Surface",
    "UnstableStateWarning",
    "boundary_surface",
    "cauchy_stress",
    "cell_field_expressions",
    "continuation_path",
    "format_summary",
    "read_convergence",
    "render_png",
    "von_mises",
]
