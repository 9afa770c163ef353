"""Runs: a problem, its solver, a step policy, and outputs that observe every accepted step.

>>> from mpi4py import MPI
>>> import hyperfem as hf
>>> from hyperfem.simulation import JSONSummary, Probe, Simulation, VTX
>>> domain = hf.beam_mesh(h=2.0)
>>> params = hf.materials.LameParameters.from_youngs(E=1e6, nu=0.3)
>>> problem = hf.HyperelasticProblem(domain, lambda F: hf.materials.neo_hookean(F, params),
...     bcs=[hf.Clamp("clamped")], loads=[hf.DeadTraction("free_end", (0, -5e3, 0))])
>>> sim = Simulation(problem, hf.NewtonSolver(problem), hf.StepPolicy(end=1.0, increment=0.5),
...     [Probe([(4.5, 1.5, 1.5)]), VTX("output/bend.bp"), JSONSummary("output/bend.json")], name="bend")
>>> summary = sim.run()

The same :class:`Simulation` runs an :class:`~hyperfem.dynamics.IncrementalProblem`
under a :class:`~hyperfem.dynamics.TimeStepping`.
"""

from hyperfem.simulation.measures import BoundaryAverage, CellFields, Probe, RadialBulge, Reaction, cauchy_stress
from hyperfem.simulation.outputs import (
    VTX,
    CSVLog,
    Derived,
    JSONSummary,
    Output,
    Progress,
    Quantity,
    Recorder,
    format_summary,
)
from hyperfem.simulation.runner import Fields, Simulation

__all__ = [
    "VTX",
    "BoundaryAverage",
    "CSVLog",
    "CellFields",
    "Derived",
    "Fields",
    "JSONSummary",
    "Output",
    "Probe",
    "Progress",
    "Quantity",
    "RadialBulge",
    "Reaction",
    "Recorder",
    "Simulation",
    "cauchy_stress",
    "format_summary",
]
