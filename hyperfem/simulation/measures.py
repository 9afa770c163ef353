r"""Mechanical measures of a run, as outputs of a :class:`~hyperfem.simulation.Simulation`.

Each adds columns to the row of every recorded state and its last value to
the summary:

* :class:`Probe` — displacement at reference points;
* :class:`Reaction` — force on the body at a named boundary
  (:class:`~hyperfem.simulation.reactions.ReactionForce`);
* :class:`BoundaryAverage` — mean of a displacement component over a boundary,
  :math:`\int_\Gamma u_i\,dA / |\Gamma|`;
* :class:`RadialBulge` — largest radial displacement away from an axis,
  :math:`\max_X \big(|(X + u)_\perp| - |X_\perp|\big)` over the displacement nodes.

:class:`CellVTX` writes cell-wise fields (fibre stretch, activation,
:func:`cauchy_stress`, ...) as a VTX time series; its interpolation,
:class:`CellFunctions`, also serves the derived fields of
:mod:`hyperfem.simulation.fields`. The reaction forces of every
Dirichlet boundary, with moments, are :class:`~hyperfem.simulation.reactions.Reactions`. All of them work on the
displacement and the three-field problem (through
:class:`~hyperfem.simulation.StateFunctions`) and, for a dynamic run, on its base problem.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TypeAlias

import numpy as np
import ufl
from dolfinx import fem, la
from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.io.probes import PointProbe
from hyperfem.kinematics import deformation_gradient
from hyperfem.materials.viscoelastic import Viscoelastic
from hyperfem.problem.mixed import MixedHyperelasticProblem, SplitEnergy
from hyperfem.simulation.outputs import VTX, Output
from hyperfem.simulation.reactions import ReactionForce
from hyperfem.solver.stepping import StepRecord

if TYPE_CHECKING:
    from dolfinx import mesh as dmesh

    from hyperfem.mesh.domain import Domain
    from hyperfem.problem.protocol import SolidProblem
    from hyperfem.simulation.runner import Simulation

__all__ = [
    "BoundaryAverage",
    "CellFunctions",
    "CellVTX",
    "Probe",
    "RadialBulge",
    "Reaction",
    "cauchy_stress",
    "quadrature_degree",
]

Expr = ufl.core.expr.Expr
Material = SplitEnergy | Callable[[Expr], Expr]
"""An energy ``psi(F)`` or a :class:`~hyperfem.problem.SplitEnergy`."""
_Compiled: TypeAlias = "tuple[np.ndarray | None, fem.Expression | tuple[fem.Form, int]]"
"""Cells (``None``: all) and how to fill them: an expression to interpolate, or an average form and its rule."""


class _Column(Output):
    """A measure with one column whose last value also goes to the summary."""

    name: str

    def summary(self, sim: Simulation, summary: dict) -> dict:
        return {self.name: sim.rows[-1][self.name]} if sim.rows else {}


class Probe(_Column):
    """Displacement at reference points, shape ``(points, components)``.

    Args:
        points: Reference coordinates.
        name: Column name (the summary adds ``probe_points``).
    """

    def __init__(self, points: Sequence[Sequence[float]], name: str = "probe_displacement"):
        self.points = [[float(c) for c in p] for p in points]
        self.name = name
        self._probe: PointProbe | None = None

    def start(self, sim: Simulation) -> None:
        """Locate the points (collective)."""
        self._probe = PointProbe(sim.fields.base.domain.mesh, self.points)

    def measure(self, sim: Simulation, step: StepRecord | None) -> dict:
        """The displacement at the points (the same on every rank)."""
        assert self._probe is not None  # located by start
        return {self.name: self._probe(sim.fields.displacement).tolist()}

    def summary(self, sim: Simulation, summary: dict) -> dict:
        """The points and their last displacement."""
        return {"probe_points": self.points, **super().summary(sim, summary)}


class Reaction(_Column):
    """Force the support exerts on the body at a named (Dirichlet) boundary.

    From the residual of the stored energy (:class:`~hyperfem.simulation.reactions.ReactionForce`);
    for a dynamic run that of the base problem: the elastic force, without inertia.
    :class:`~hyperfem.simulation.reactions.Reactions` gives force and moment of
    every Dirichlet boundary from the full residual (loads on the boundary and,
    for a dynamic run, inertia included).

    Args:
        boundary: Boundary name.
        name: Column name (default ``reaction_<boundary>``).
    """

    def __init__(self, boundary: str, name: str | None = None):
        self.boundary = boundary
        self.name = name or f"reaction_{boundary}"
        self._force: ReactionForce | None = None

    def start(self, sim: Simulation) -> None:
        """Compile the form."""
        self._force = ReactionForce(sim.fields.base, self.boundary)

    def measure(self, sim: Simulation, step: StepRecord | None) -> dict:
        """The force vector."""
        assert self._force is not None  # compiled by start
        return {self.name: self._force().tolist()}


class BoundaryAverage(_Column):
    r"""Mean displacement component over a named boundary, :math:`\int_\Gamma u_i\,dA / |\Gamma|`.

    Args:
        boundary: Boundary name.
        component: Displacement component ``i``.
        name: Column name (default ``u<i>_<boundary>``).

    Attributes:
        area: :math:`|\Gamma|` in the reference configuration (after :meth:`start`).
    """

    def __init__(self, boundary: str, component: int, name: str | None = None):
        self.boundary = boundary
        self.component = component
        self.name = name or f"u{component}_{boundary}"
        self.area = float("nan")

    def start(self, sim: Simulation) -> None:
        """Compile the form and measure the boundary."""
        domain = sim.fields.base.domain
        if not 0 <= self.component < domain.gdim:
            raise ParameterError(f"BoundaryAverage: component must lie in [0, {domain.gdim}), got {self.component!r}")
        ds = domain.ds(self.boundary)
        self._comm = domain.comm
        self.area = domain.comm.allreduce(fem.assemble_scalar(fem.form(1.0 * ds)))
        self._form = fem.form(sim.fields.displacement[self.component] * ds)

    def measure(self, sim: Simulation, step: StepRecord | None) -> dict:
        """The mean."""
        return {self.name: self._comm.allreduce(fem.assemble_scalar(self._form)) / self.area}


class RadialBulge(_Column):
    r"""Largest radial displacement away from an axis, :math:`\max_X\big(|(X + u)_\perp| - |X_\perp|\big)`.

    :math:`Y_\perp = (Y - c) - ((Y - c)\cdot a)\,a` is the part of :math:`Y - c`
    normal to the axis through ``origin`` :math:`c` along ``axis`` :math:`a`; the
    maximum runs over the displacement nodes.

    Args:
        axis: Direction of the axis.
        origin: A point of the axis.
        name: Column name.
    """

    def __init__(
        self,
        axis: Sequence[float] = (0.0, 0.0, 1.0),
        origin: Sequence[float] = (0.0, 0.0, 0.0),
        name: str = "max_radial_bulge",
    ):
        a = np.asarray(axis, dtype=float)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or not np.linalg.norm(a) > 0:
            raise ParameterError(f"RadialBulge: axis must be a finite non-zero 3-vector, got {axis!r}")
        self.axis = a / np.linalg.norm(a)
        self.origin = np.asarray(origin, dtype=float)
        self.name = name

    def _perp(self, Y: np.ndarray) -> np.ndarray:
        d = Y - self.origin
        return d - np.outer(d @ self.axis, self.axis)

    def start(self, sim: Simulation) -> None:
        """Tabulate the node coordinates."""
        space = sim.fields.displacement.function_space
        self._X = space.tabulate_dof_coordinates()
        self._gdim = space.dofmap.index_map_bs
        self._r0 = np.sqrt((self._perp(self._X) ** 2).sum(axis=1))
        self._comm = space.mesh.comm

    def measure(self, sim: Simulation, step: StepRecord | None) -> dict:
        """The bulge (``-inf`` on a rank without nodes before the reduction)."""
        u = np.zeros_like(self._X)
        u[:, : self._gdim] = sim.fields.displacement.x.array.reshape(-1, self._gdim)
        r = np.sqrt((self._perp(self._X + u) ** 2).sum(axis=1))
        local = float((r - self._r0).max()) if r.size else -np.inf
        return {self.name: self._comm.allreduce(local, op=MPI.MAX)}


def cauchy_stress(
    problem: SolidProblem, materials: Mapping[str | None, SplitEnergy | Callable[[Expr], Expr]]
) -> dict[str | None, Expr]:
    r"""Cauchy stress :math:`\sigma = J^{-1} P F^T`, :math:`P = \partial W/\partial F`, per region.

    For the three-field problem :math:`W = \psi_\text{iso}(F) + U(\theta) + p\,(\det F - \theta)`
    at the problem's :math:`p, \theta` (the stress of the mixed solution; a
    :class:`~hyperfem.materials.viscoelastic.Viscoelastic` material: its
    :meth:`~hyperfem.materials.viscoelastic.Viscoelastic.mixed_energy`, the isochoric
    part of the step with its frozen history, so
    :math:`P = F(\gamma S_\text{iso} + B_n) + p\,\operatorname{cof}F`);
    for the displacement problem :math:`W = \psi(F)`.

    Args:
        problem: The displacement or three-field problem.
        materials: Region name (``None``: everywhere) → :class:`~hyperfem.problem.SplitEnergy`
            (or :class:`~hyperfem.materials.viscoelastic.Viscoelastic`) or energy ``psi(F)``.

    Returns:
        Region → UFL tensor, for :class:`CellVTX`.
    """
    F = ufl.variable(deformation_gradient(problem.displacement()))
    mixed = problem if isinstance(problem, MixedHyperelasticProblem) else None
    out = {}
    for region, material in materials.items():
        if mixed is not None:
            if not isinstance(material, (SplitEnergy, Viscoelastic)):
                raise ParameterError(
                    f"cauchy_stress: the three-field problem needs SplitEnergy or Viscoelastic materials ({region!r})"
                )
            W = material.mixed_energy(F, mixed.p, mixed.theta)
        else:
            W = material.energy(F) if isinstance(material, SplitEnergy) else material(F)
        out[region] = ufl.diff(W, F) * F.T / ufl.det(F)
    return out


class CellFunctions:
    """Expressions interpolated into cell-wise functions (DG of a given degree), per region.

    The machinery of :class:`CellVTX` and of
    :class:`~hyperfem.simulation.fields.FieldOutput`: compiled once, refreshed
    before every frame.

    Args:
        domain: The :class:`~hyperfem.mesh.Domain`.
        fields: Name → UFL expression (or number), or name → {region → expression}
            (cells outside the listed regions are zero).
        degree: Degree of the discontinuous Lagrange space (0: one value per
            cell, at its midpoint).

    Attributes:
        functions: The functions, in the order of ``fields``.
    """

    def __init__(
        self, domain: Domain, fields: Mapping[str, Expr | float | Mapping[str | None, Expr | float]], degree: int = 0
    ) -> None:
        if not (isinstance(degree, numbers.Integral) and not isinstance(degree, bool) and degree >= 0):
            raise ParameterError(f"CellVTX: degree must be an integer >= 0, got {degree!r}")
        mesh = domain.mesh
        self._parts: list[tuple[fem.Function, list[_Compiled]]] = []
        self.functions: list[fem.Function] = []
        self._volumes: dict[int, fem.Function] = {}
        for name, spec in fields.items():
            parts = dict(spec) if isinstance(spec, Mapping) else {None: spec}
            parts = {r: fem.Constant(mesh, float(e)) if isinstance(e, numbers.Real) else e for r, e in parts.items()}
            shape = next(iter(parts.values())).ufl_shape
            V = fem.functionspace(mesh, ("DG", degree, shape) if shape else ("DG", degree))
            f = fem.Function(V, name=name)
            points = V.element.interpolation_points
            compiled: list[_Compiled] = []
            for region, e in parts.items():
                cells = None if region is None else domain.cells(region)
                rule = quadrature_degree(e)
                if rule is None:
                    compiled.append((cells, fem.Expression(e, points)))
                elif degree == 0:
                    # values kept at quadrature points (a material's rotation field) have no midpoint value:
                    # the cell average on their rule instead
                    w = ufl.TestFunction(V)
                    dx = ufl.dx(domain=mesh, metadata={"quadrature_degree": rule})
                    compiled.append((cells, (fem.form(ufl.inner(e, w) * dx), rule)))
                else:
                    raise ParameterError(
                        f"CellVTX: {name} depends on values kept at quadrature points; it has cell values "
                        f"(degree 0), not degree {degree}"
                    )
            self._parts.append((f, compiled))
            self.functions.append(f)

    def _cell_volumes(self, mesh: dmesh.Mesh, rule: int) -> fem.Function:
        """Cell volumes on the quadrature rule of degree ``rule`` (that of the averages: exact ratio for constants)."""
        if rule not in self._volumes:
            V0 = fem.functionspace(mesh, ("DG", 0))
            volumes = fem.Function(V0)
            dx = ufl.dx(domain=mesh, metadata={"quadrature_degree": rule})
            b = fem.assemble_vector(fem.form(ufl.TestFunction(V0) * dx))
            b.scatter_reverse(la.InsertMode.add)
            b.scatter_forward()
            volumes.x.array[:] = b.array
            self._volumes[rule] = volumes
        return self._volumes[rule]

    def _average(self, f: fem.Function, form: fem.Form, rule: int, cells: np.ndarray | None) -> None:
        """``f`` on ``cells`` (all for ``None``) := the cell averages, ∫ e w dx / |K|."""
        mesh = f.function_space.mesh
        b = fem.assemble_vector(form)
        b.scatter_reverse(la.InsertMode.add)
        b.scatter_forward()
        bs = f.function_space.dofmap.bs
        volumes = self._cell_volumes(mesh, rule)
        tdim = mesh.topology.dim
        if cells is None:
            cmap = mesh.topology.index_map(tdim)
            cells = np.arange(cmap.size_local + cmap.num_ghosts, dtype=np.int32)
        dofs = f.function_space.dofmap.list[cells, 0]
        vdofs = volumes.function_space.dofmap.list[cells, 0]
        values = f.x.array.reshape(-1, bs)
        values[dofs] = b.array.reshape(-1, bs)[dofs] / volumes.x.array[vdofs, None]

    def refresh(self) -> None:
        """Interpolate every expression at the current state (cell averages where the expression needs them)."""
        for f, compiled in self._parts:
            for cells, expr in compiled:
                if isinstance(expr, tuple):
                    form, rule = expr
                    self._average(f, form, rule, cells)
                elif cells is None:
                    f.interpolate(expr)
                else:
                    f.interpolate(expr, cells0=cells)
            f.x.scatter_forward()


def quadrature_degree(e: Expr) -> int | None:
    """The rule of the quadrature-space coefficients in ``e`` (their highest degree), or ``None`` if it has none."""
    from ufl.algorithms import extract_coefficients

    degrees = [
        int(c.ufl_function_space().ufl_element().degree)
        for c in extract_coefficients(e)
        # Boundary: only basix elements (third-party) say whether they are quadrature elements.
        if getattr(c.ufl_function_space().ufl_element(), "is_quadrature", False)
    ]
    return max(degrees) if degrees else None


class CellVTX(VTX):
    """Cell-wise fields (DG0 at cell midpoints, or DG of a higher degree) as a VTX time series.

    Args:
        path: The ``.bp`` folder.
        fields: Name → UFL expression (or number), or name → {region → expression}
            (cells outside the listed regions are zero).
        times: As for :class:`~hyperfem.simulation.outputs.VTX`.
        role: Key in ``sim.files`` (default: the file name).
        degree: Degree of the discontinuous space (0: one value per cell;
            ``k - 1`` follows the stress of a degree-k displacement).
    """

    def __init__(
        self,
        path: str | Path,
        fields: Mapping[str, Expr | float | Mapping[str | None, Expr | float]],
        *,
        times: Sequence[float] | None = None,
        role: str | None = None,
        degree: int = 0,
    ):
        super().__init__(path, None, times=times, role=role or Path(path).name)
        self.fields = dict(fields)
        self.degree = degree
        self._cells: CellFunctions | None = None

    def start(self, sim: Simulation) -> None:
        """Compile the expressions and open the file."""
        self._cells = CellFunctions(sim.fields.base.domain, self.fields, self.degree)
        self.functions = self._cells.functions
        super().start(sim)

    def _refresh(self) -> None:
        assert self._cells is not None  # compiled by start
        self._cells.refresh()
