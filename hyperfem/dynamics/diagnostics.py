r"""Per-step diagnostics of a time-dependent run, written to CSV and JSON.

For every accepted step :class:`Diagnostics` records

* the current position :math:`x = X + u(X)` of probe points (the motion curve),
* kinetic energy :math:`K = \tfrac12\int\rho\,v\cdot v\,dX`, stored (elastic)
  energy :math:`\Psi = \int\psi(F)\,dX`, dead-load work :math:`W` and the total
  :math:`K + \Psi - W` (conserved by an exact undamped flow under constant dead loads),
* the total volume ratio :math:`\int J\,dX / |\Omega|` (volume gain
  :math:`= \text{ratio} - 1`),
* :math:`\min J` over quadrature points and the number of cells with
  :math:`J \le 0` at some quadrature point (seed 003, table 5.4),
* step size, Newton iterations, solves and rejected attempts.

All reductions use ``mesh.comm``; only rank 0 writes files.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import ufl
from mpi4py import MPI
from dolfinx import fem, geometry

from hyperfem.dynamics.stepping import TimeStepRecord
from hyperfem.errors import ParameterError
from hyperfem.io.results import on_rank0

__all__ = ["Diagnostics", "PointProbe"]


class PointProbe:
    """Evaluate a function at fixed reference points in parallel.

    Each point is evaluated by the lowest rank that owns a cell containing it.
    """

    def __init__(self, mesh, points: Sequence[Sequence[float]]):
        try:
            self.points = np.array([list(p) + [0.0] * (3 - len(p)) for p in points], dtype=float).reshape(-1, 3)
        except (TypeError, ValueError):
            raise ParameterError(f"PointProbe: points must be sequences of 1 to 3 numbers, got {points!r}") from None
        if not np.all(np.isfinite(self.points)):
            raise ParameterError(f"PointProbe: points must be finite, got {self.points.tolist()}")
        tdim = mesh.topology.dim
        owned = np.arange(mesh.topology.index_map(tdim).size_local, dtype=np.int32)
        tree = geometry.bb_tree(mesh, tdim, entities=owned)
        candidates = geometry.compute_collisions_points(tree, self.points)
        colliding = geometry.compute_colliding_cells(mesh, candidates, self.points)
        comm = mesh.comm
        self.comm = comm
        self._cells = []
        for i in range(len(self.points)):
            links = colliding.links(i)
            mine = comm.rank if len(links) else comm.size
            owner = comm.allreduce(mine, op=MPI.MIN)
            if owner == comm.size:
                raise ParameterError(f"PointProbe: point {self.points[i].tolist()} is outside the mesh")
            self._cells.append(int(links[0]) if owner == comm.rank else -1)

    def __call__(self, f: fem.Function) -> np.ndarray:
        """Values of ``f`` at the points, shape ``(npoints, value_size)``, on every rank."""
        size = int(np.prod(f.function_space.value_shape)) if f.function_space.value_shape else 1
        out = np.zeros((len(self.points), size))
        for i, cell in enumerate(self._cells):
            if cell >= 0:
                out[i] = f.eval(self.points[i], np.array([cell], dtype=np.int32))
        return self.comm.allreduce(out, op=MPI.SUM)


class Diagnostics:
    """Collect one row of diagnostics per accepted step.

    Args:
        problem: The :class:`~hyperfem.dynamics.IncrementalProblem`.
        probes: Reference points whose current position is recorded.
    """

    def __init__(self, problem, probes: Sequence[Sequence[float]] = ()):
        self.problem = problem
        base = problem.base
        domain = problem.domain
        mesh = domain.mesh
        gdim = domain.gdim
        md = {"quadrature_degree": base.quadrature_degree}
        J = base.volume_jacobian()
        self._volume_current = fem.form(J * domain.dx(metadata=md))
        one = fem.Constant(mesh, 1.0)
        volume0 = fem.assemble_scalar(fem.form(one * ufl.dx(domain=mesh)))
        self.reference_volume = float(domain.comm.allreduce(volume0, op=MPI.SUM))
        self._J_expr = fem.Expression(J, base.quadrature_points())
        tdim = mesh.topology.dim
        self._cells = np.arange(mesh.topology.index_map(tdim).size_local, dtype=np.int32)
        self.probe_points = [tuple(float(c) for c in p) for p in probes]
        self._probe = PointProbe(mesh, self.probe_points) if self.probe_points else None
        self._gdim = gdim
        self.rows: list[dict] = []

    def jacobian_stats(self) -> tuple[float, int]:
        """``(min J over quadrature points, number of cells with J <= 0 somewhere)``."""
        vals = self._J_expr.eval(self.problem.domain.mesh, self._cells)
        comm = self.problem.domain.comm
        if vals.size:
            per_cell = vals.reshape(len(self._cells), -1).min(axis=1)
            local_min, local_bad = float(per_cell.min()), int((per_cell <= 0).sum())
        else:
            local_min, local_bad = np.inf, 0
        return comm.allreduce(local_min, op=MPI.MIN), comm.allreduce(local_bad, op=MPI.SUM)

    def volume_ratio(self) -> float:
        r""":math:`\int J\,dX / |\Omega|`."""
        comm = self.problem.domain.comm
        return float(comm.allreduce(fem.assemble_scalar(self._volume_current), op=MPI.SUM)) / self.reference_volume

    def record(self, step: TimeStepRecord | None = None) -> dict:
        """Append (and return) the diagnostics of the current state."""
        p = self.problem
        kinetic = p.kinetic_energy()
        elastic = p.elastic_energy()
        work = p.external_work()
        minJ, inverted = self.jacobian_stats()
        row = {
            "step": 0 if step is None else step.step,
            "time": p.time,
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
            disp = self._probe(p.u)
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

    def write_csv(self, path: str | Path) -> None:
        """Write all rows to ``path`` (rank 0 writes; every rank must call).

        Raises:
            OutputError: On every rank, if the file cannot be written.
        """
        if not self.rows:
            return
        path = Path(path)

        def write() -> None:
            path.parent.mkdir(parents=True, exist_ok=True)
            with path.open("w", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=list(self.rows[0]))
                writer.writeheader()
                writer.writerows(self.rows)

        on_rank0(self.problem.domain.comm, write, f"cannot write {path}")

    def write_json(self, path: str | Path, extra: dict | None = None) -> None:
        """Write the summary (plus ``extra``) to ``path`` (rank 0 writes; every rank must call).

        Raises:
            OutputError: On every rank, if the file cannot be written.
        """
        path = Path(path)
        text = json.dumps({**(extra or {}), "summary": self.summary()}, indent=2, default=str)

        def write() -> None:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)

        on_rank0(self.problem.domain.comm, write, f"cannot write {path}")
