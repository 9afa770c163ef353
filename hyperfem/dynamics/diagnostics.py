r"""Per-step diagnostics of a time-dependent run: measured here, written by the run's outputs.

For every accepted step :class:`Diagnostics` records

* the current position :math:`x = X + u(X)` of probe points (the motion curve),
* kinetic energy :math:`K = \tfrac12\int\rho\,v\cdot v\,dX`, stored energy
  :math:`\Pi_\text{int}` (:math:`\int\psi(F)\,dX` for the displacement
  problem), dead-load work :math:`W` and the total :math:`K + \Pi_\text{int} - W`
  (conserved by an exact undamped flow under constant dead loads),
* the total volume ratio :math:`\int \det F\,dX / |\Omega|` (volume gain
  :math:`= \text{ratio} - 1`),
* the minimum over quadrature points of the problem's inversion measure
  (:math:`J = \det F`; :math:`\min(J, \theta)` for the three-field problem) and
  the number of cells where it is :math:`\le 0` somewhere (seed 003, table 5.4),
* step size, Newton iterations, solves and rejected attempts.

Everything goes through the problem contract
(:class:`~hyperfem.problem.protocol.SolidProblem`), so the displacement and the
three-field problem are treated alike; the explicit scheme
(:class:`~hyperfem.dynamics.ExplicitDynamics`) offers the same members. All
reductions use ``mesh.comm``.

:class:`Diagnostics` writes no files. In a run it is a
:class:`~hyperfem.simulation.Recorder`: its columns join the run's rows, which
:class:`~hyperfem.simulation.CSVLog` writes as CSV and
:class:`~hyperfem.simulation.JSONSummary` as JSON (with :meth:`Diagnostics.summary`)::

    diagnostics = Diagnostics(problem, [(4.5, 1.5, 1.5)])
    outputs = [Recorder(diagnostics), CSVLog("out/diagnostics.csv"), JSONSummary("out/summary.json")]
    Simulation(problem, NewtonSolver(problem), stepping, outputs).run()
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import ufl
from mpi4py import MPI
from dolfinx import fem

from hyperfem.dynamics.incremental import IncrementalProblem
from hyperfem.solver.stepping import StepRecord
from hyperfem.io.probes import PointProbe
from hyperfem.problem.inversion import QuadratureMinimum

__all__ = ["Diagnostics"]


class Diagnostics:
    """Collect one row of diagnostics per accepted step.

    Args:
        problem: The :class:`~hyperfem.dynamics.IncrementalProblem`.
        probes: Reference points whose current position is recorded
            (columns ``p<i>_x``, ``p<i>_y``, ...).
    """

    def __init__(self, problem: IncrementalProblem, probes: Sequence[Sequence[float]] = ()):
        self.problem = problem
        domain = problem.domain
        mesh = domain.mesh
        md = {"quadrature_degree": problem.quadrature_degree}
        u = problem.displacement()
        J = ufl.det(ufl.Identity(domain.gdim) + ufl.grad(u))
        self._volume_current = fem.form(J * domain.dx(metadata=md))
        one = fem.Constant(mesh, 1.0)
        volume0 = fem.assemble_scalar(fem.form(one * ufl.dx(domain=mesh)))
        self.reference_volume = float(domain.comm.allreduce(volume0, op=MPI.SUM))
        self._min_J = QuadratureMinimum(mesh, problem.volume_jacobian(), problem.quadrature_points())
        self.probe_points = [tuple(float(c) for c in p) for p in probes]
        self._probe = PointProbe(mesh, self.probe_points) if self.probe_points else None
        self._gdim = domain.gdim
        self.rows: list[dict] = []

    def jacobian_stats(self) -> tuple[float, int]:
        """``(min J over quadrature points, number of cells with J <= 0 somewhere)``."""
        return self._min_J.with_count(0.0)

    def volume_ratio(self) -> float:
        r""":math:`\int \det F\,dX / |\Omega|`."""
        comm = self.problem.domain.comm
        return float(comm.allreduce(fem.assemble_scalar(self._volume_current), op=MPI.SUM)) / self.reference_volume

    def record(self, step: StepRecord | None = None) -> dict:
        """Append (and return) the diagnostics of the current state."""
        p = self.problem
        kinetic = p.kinetic_energy()
        elastic = p.elastic_energy()
        work = p.external_work()
        minJ, inverted = self.jacobian_stats()
        row = {
            "step": 0 if step is None else step.step,
            "time": p.t_n,
            "dt": 0.0 if step is None else step.dt,
            "newton_iterations": 0 if step is None else step.iterations,
            "solves": 0 if step is None else step.solves,
            "rejected": 0 if step is None else step.rejected,
            "error_estimate": float("nan") if step is None else step.error,
            "kinetic_energy": kinetic,
            "elastic_energy": elastic,
            "external_work": work,
            "total_energy": kinetic + elastic - work,
            "volume_ratio": self.volume_ratio(),
            "min_J": minJ,
            "inverted_cells": inverted,
        }
        if self._probe is not None:
            disp = self._probe(p.displacement_block.function(p.u))
            axes = "xyz"[: self._gdim]
            for i, X in enumerate(self.probe_points):
                for k, ax in enumerate(axes):
                    row[f"p{i}_{ax}"] = X[k] + float(disp[i, k])
        self.rows.append(row)
        return row

    def column(self, name: str) -> np.ndarray:
        """One diagnostic over all recorded rows."""
        return np.array([r[name] for r in self.rows], dtype=float)

    def summary(self) -> dict:
        """Aggregates: steps, average/min/max dt, Newton iterations per step, min J, volume gain."""
        steps = [r for r in self.rows if r["step"] > 0]
        dts = np.array([r["dt"] for r in steps]) if steps else np.zeros(1)
        its = np.array([r["newton_iterations"] for r in steps]) if steps else np.zeros(1)
        vol = self.column("volume_ratio")
        return {
            "steps": len(steps),
            "dt_avg": float(dts.mean()),
            "dt_min": float(dts.min()),
            "dt_max": float(dts.max()),
            "dt_std": float(dts.std()),
            "newton_iterations_per_step": float(its.mean()),
            "solves": int(sum(r["solves"] for r in steps)),
            "rejected": int(sum(r["rejected"] for r in steps)),
            "min_J": float(self.column("min_J").min()),
            "max_inverted_cells": int(self.column("inverted_cells").max()),
            "volume_gain_min": float(vol.min() - 1.0),
            "volume_gain_max": float(vol.max() - 1.0),
            "final_time": float(self.rows[-1]["time"]) if self.rows else 0.0,
        }
