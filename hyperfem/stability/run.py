r"""A linearised buckling analysis as a run: what ``[stepping] type = "buckling"`` of a case file builds.

:class:`BucklingRun` has the shape of a :class:`~hyperfem.simulation.Simulation`
for the ``hyperfem run`` command (``run()`` returns a summary dict), but it takes
no steps: at the reference load factor ``reference`` (0: the unloaded body; a
ramp solves for the equilibrium there first) it calls
:func:`~hyperfem.stability.buckling_analysis` with the load increment
``increment`` and writes

* ``NAME.json``: the critical load factors :math:`t_\text{cr} = t_0 + \mu\,\Delta t`
  (ascending), the multipliers, those of reversed loading, the reference;
* ``NAME_modes.bp``: the modes, one VTX frame each (ParaView: warp by
  ``buckling_mode``).
"""

from __future__ import annotations

import json
import time as _time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hyperfem.errors import ParameterError
from hyperfem.io.results import ensure_output_dir, jsonable
from hyperfem.problem.protocol import SolidProblem
from hyperfem.solver.newton import NewtonSolver
from hyperfem.solver.stepping import LoadStepping, solve_quasistatic
from hyperfem.stability.buckling import PRESTRESS, buckling_analysis, write_buckling_modes
from hyperfem.validation import check_count, check_finite_scalar

__all__ = ["Buckling", "BucklingRun"]


@dataclass(frozen=True)
class Buckling:
    """Settings of a linearised buckling analysis (see the module docstring).

    Attributes:
        n: Critical load factors (and modes) wanted.
        increment: The load increment :math:`\\Delta t` of the second tangent.
        prestress: ``"linear"`` (one linear solve, Abaqus ``*BUCKLE``) or ``"nonlinear"`` (a Newton solve).
        reference: The load factor of the reference state (reached by a ramp when not 0).
    """

    n: int = 2
    increment: float = 1.0
    prestress: str = "linear"
    reference: float = 0.0

    def __post_init__(self) -> None:
        where = "Buckling"
        check_count("n", self.n, where)
        check_finite_scalar(self.increment, where, "increment")
        check_finite_scalar(self.reference, where, "reference")
        if self.increment == 0.0:
            raise ParameterError(f"{where}: increment must not be 0")
        if self.prestress not in PRESTRESS:
            raise ParameterError(f"{where}: prestress must be one of {PRESTRESS}, got {self.prestress!r}")


class BucklingRun:
    """A buckling analysis of a problem, run like a simulation (module docstring).

    Args:
        problem: The problem (displacement or mixed).
        solver: Its Newton solver (the ramp to the reference; the nonlinear prestress).
        settings: The analysis.
        folder: The output folder.
        name: Name of the run (file names, summary).
    """

    kind = "buckling"

    def __init__(
        self, problem: SolidProblem, solver: NewtonSolver, settings: Buckling, folder: str | Path, name: str = "run"
    ) -> None:
        self.problem = problem
        self.solver = solver
        self.settings = settings
        self.folder = Path(folder)
        self.name = name
        self.comm = problem.domain.comm

    def run(self, restart: str | Path | None = None) -> dict[str, Any]:
        """Reach the reference state, solve for the critical load factors and modes, write them; the summary.

        Raises:
            ParameterError: ``restart`` given (a buckling analysis has no steps to continue).
            ConvergenceError: The ramp to the reference, or the nonlinear prestress, failed.
        """
        if restart is not None:
            raise ParameterError(f"{self.name}: a buckling analysis has no steps to continue (no --restart)")
        s = self.settings
        start = _time.perf_counter()
        ensure_output_dir(self.folder, self.comm)
        steps = solve_quasistatic(self.solver, s.reference, LoadStepping()) if s.reference != 0.0 else []
        solver = self.solver if s.prestress == "nonlinear" else None
        result = buckling_analysis(self.problem, s.n, increment=s.increment, prestress=s.prestress, solver=solver)
        modes = self.folder / f"{self.name}_modes.bp"
        written = {}
        if result.modes:
            write_buckling_modes(result, modes, self.comm)
            written["modes"] = str(modes)
        dofmap = self.problem.u.function_space.dofmap
        mesh = self.problem.domain.mesh
        summary: dict[str, Any] = {
            "name": self.name,
            "stage": self.kind,
            "completed": True,
            "dofs": int(dofmap.index_map.size_global * dofmap.index_map_bs),
            "cells": int(mesh.topology.index_map(mesh.topology.dim).size_global),
            "ranks": self.comm.size,
            "steps": len(steps),
            "newton_iterations": [r.iterations for r in steps],
            "buckling": result.as_dict(),
            "critical_load_factors": list(result.load_factors),
            "files": {"summary": str(self.folder / f"{self.name}.json"), **written},
            "wall_time": _time.perf_counter() - start,
        }
        if self.comm.rank == 0:
            (self.folder / f"{self.name}.json").write_text(json.dumps(jsonable(summary), indent=2))
        self.comm.Barrier()
        return summary
