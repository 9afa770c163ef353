r"""Derived output fields: displacement, Cauchy stress, von Mises stress, :math:`J`, fibre stretch, activation.

:class:`FieldOutput` writes them as time series for ParaView, in VTX (ADIOS2,
the default) or XDMF:

* ``displacement`` — the nodal fields of the run
  (:meth:`~hyperfem.simulation.StateFunctions.output`: displacement; pressure of the
  three-field problem; velocity of a dynamic run);
* ``cauchy_stress`` — :math:`\sigma = J^{-1} P F^T`, :math:`P = \partial W/\partial F`
  per region (:func:`~hyperfem.simulation.measures.cauchy_stress`; the mixed
  problem's stress at its :math:`p, \theta`), a 3×3 tensor per cell;
* ``von_mises`` — :func:`von_mises` of that stress;
* ``J`` — :math:`\det F`;
* ``fibre_stretch`` — :math:`\lambda = \sqrt{a_0\cdot C a_0}` of a unit fibre field :math:`a_0`;
* ``activation`` — the muscle activation :math:`\alpha(X, t)` (zero outside its region).

Cell fields are interpolated into discontinuous Lagrange of degree ``degree``
(0: one value per cell, at its midpoint; ``"auto"``: degree :math:`k - 1` of
a P\ :sub:`k` displacement, the degree of its gradient). VTX keeps those
degrees, with the nodal and the cell fields in two files (``<name>.bp``,
``<name>_cells.bp``, as VTX stores one element per file). XDMF (``<name>.xdmf``)
holds one mesh with nodal values at its geometry nodes and one value per
cell, so nodal fields are interpolated to P1 there and cell fields must be DG0.

Frames are written at the initial state and after every step (or at given
times): a killed run keeps every complete VTX frame.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TypeAlias, cast

import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import deformation_gradient
from hyperfem.simulation.measures import CellFunctions, Material, cauchy_stress
from hyperfem.simulation.outputs import VTX, XDMF, Output
from hyperfem.solver.stepping import StepRecord

if TYPE_CHECKING:
    from dolfinx import fem

    from hyperfem.loading.activation import Activation
    from hyperfem.problem.protocol import SolidProblem
    from hyperfem.simulation.runner import Simulation

__all__ = ["DEFAULT_FIELDS", "FIELDS", "FORMATS", "FieldOutput", "cell_field_expressions", "von_mises"]

FIELDS = ("displacement", "cauchy_stress", "von_mises", "J", "fibre_stretch", "activation")
"""Every field :class:`FieldOutput` knows."""

DEFAULT_FIELDS = ("displacement", "cauchy_stress", "von_mises", "J")
"""What :class:`FieldOutput` writes unless told otherwise (stress fields need ``materials``)."""

FORMATS = ("vtx", "xdmf")
"""File formats of :class:`FieldOutput`."""

_NEEDS_MATERIALS = ("cauchy_stress", "von_mises")

Expr = ufl.core.expr.Expr
Materials = Material | Mapping[str, Material] | Mapping[str | None, Material]
"""One energy for the whole body, or region name (``None``: everywhere) → energy."""
ActivationPart: TypeAlias = "Activation | Expr | float"
ActivationSpec: TypeAlias = "ActivationPart | Mapping[str, ActivationPart] | Mapping[str | None, ActivationPart]"
"""An :class:`~hyperfem.loading.Activation` (or its expression), or region name → one."""


def von_mises(sigma: Expr) -> Expr:
    r"""Von Mises equivalent stress :math:`\sqrt{\tfrac32\,s:s}`, :math:`s = \operatorname{dev}\sigma`.

    Written as :math:`\sqrt{\tfrac32\,\sigma:\sigma - \tfrac12(\operatorname{tr}\sigma)^2}`, which
    for a 2×2 tensor is the plane-stress value (:math:`\sigma_{zz} = 0`).
    Uniaxial stress :math:`s` gives :math:`|s|`, pure shear :math:`\tau` gives :math:`\sqrt3|\tau|`.
    """
    tr = ufl.tr(sigma)
    return ufl.sqrt(ufl.max_value(1.5 * ufl.inner(sigma, sigma) - 0.5 * tr**2, 0.0))


def _check_names(fields: Sequence[str]) -> list[str]:
    if isinstance(fields, str):
        fields = [fields]
    names = list(fields)
    for name in names:
        if name not in FIELDS:
            close = difflib.get_close_matches(str(name), FIELDS, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ParameterError(f"FieldOutput: unknown field {name!r}{hint}; known: {', '.join(FIELDS)}")
    return names


def _activation_parts(activation: ActivationSpec) -> Mapping[str | None, Expr | float]:
    # Boundary: a user activation is an Activation (with .expr) or a plain UFL expression / number.
    if isinstance(activation, Mapping):
        return {r: _expression(a) for r, a in activation.items()}
    return {None: _expression(activation)}


def _expression(part: ActivationPart) -> Expr | float:
    """The ``expr`` of an activation (or of any object with one), else the expression or number itself."""
    expr = getattr(part, "expr", None)
    return cast("Expr | float", part) if expr is None else expr


def cell_field_expressions(
    problem: SolidProblem,
    names: Sequence[str],
    materials: Materials | None = None,
    *,
    fibres: fem.Function | None = None,
    activation: ActivationSpec | None = None,
) -> dict[str, Expr | float | Mapping[str | None, Expr | float]]:
    """The UFL expressions of the cell fields among ``names`` (``displacement`` is not one).

    Args:
        problem: The displacement or three-field problem (the base of a dynamic run).
        names: Field names (:data:`FIELDS`).
        materials: Region name (``None``: everywhere) → energy ``psi(F)`` or
            :class:`~hyperfem.problem.SplitEnergy`, or one of them for the
            whole body; needed by the stress fields.
        fibres: Unit fibre field :math:`a_0` (DG0, P1: evaluated at the cell
            field's points), for ``fibre_stretch``.
        activation: An :class:`~hyperfem.loading.Activation` (or its
            expression), or region name → one, for ``activation``.

    Returns:
        Name → expression or {region → expression}, for
        :class:`~hyperfem.simulation.measures.CellFunctions`.

    Raises:
        ParameterError: An unknown name, or a field without what it needs.
    """
    names = _check_names(names)
    out: dict[str, Expr | float | Mapping[str | None, Expr | float]] = {}
    F = deformation_gradient(problem.displacement())
    if any(n in names for n in _NEEDS_MATERIALS):
        if materials is None:
            raise ParameterError("FieldOutput: cauchy_stress and von_mises need materials= (region -> energy)")
        mapping: dict[str | None, Material]
        mapping = dict(materials.items()) if isinstance(materials, Mapping) else {None: materials}
        sigma = cauchy_stress(problem, mapping)
        if "cauchy_stress" in names:
            out["cauchy_stress"] = sigma
        if "von_mises" in names:
            out["von_mises"] = {region: von_mises(s) for region, s in sigma.items()}
    if "J" in names:
        out["J"] = ufl.det(F)
    if "fibre_stretch" in names:
        if fibres is None:
            raise ParameterError("FieldOutput: fibre_stretch needs fibres= (the unit fibre field a0)")
        from hyperfem.materials.muscle import fibre_stretch

        out["fibre_stretch"] = fibre_stretch(F, fibres)
    if "activation" in names:
        if activation is None:
            raise ParameterError("FieldOutput: activation needs activation= (an Activation, or region -> Activation)")
        out["activation"] = dict(_activation_parts(activation))
    return out


class FieldOutput(Output):
    """The derived fields of a run as a ParaView time series (module docstring).

    Args:
        folder: Output folder.
        materials: The energies, for the stress fields (see :func:`cell_field_expressions`).
        fields: Which fields (:data:`FIELDS`; default :data:`DEFAULT_FIELDS`).
        fibres: Unit fibre field, for ``fibre_stretch``.
        activation: Activation(s), for ``activation``.
        format: ``"vtx"`` (default) or ``"xdmf"``.
        degree: Degree of the cell fields: an integer >= 0 or ``"auto"``
            (displacement degree − 1); XDMF takes 0 only.
        times: Write only when passing these times (as :class:`~hyperfem.simulation.outputs.VTX`).
        name: Start of the file names.

    Files (``sim.files`` roles): VTX ``<name>.bp`` (role ``name``) and
    ``<name>_cells.bp`` (``<name>_cells``); XDMF ``<name>.xdmf`` (role ``name``).

    Raises:
        ParameterError: Unknown field or format, a bad degree, or degree > 0 with XDMF.
    """

    def __init__(
        self,
        folder: str | Path,
        materials: Materials | None = None,
        *,
        fields: Sequence[str] = DEFAULT_FIELDS,
        fibres: fem.Function | None = None,
        activation: ActivationSpec | None = None,
        format: str = "vtx",
        degree: int | str = 0,
        times: Sequence[float] | None = None,
        name: str = "fields",
    ):
        self.names = _check_names(fields)
        if format not in FORMATS:
            raise ParameterError(f"FieldOutput: format must be one of {', '.join(FORMATS)}, got {format!r}")
        if degree != "auto" and not (isinstance(degree, int) and not isinstance(degree, bool) and degree >= 0):
            raise ParameterError(f"FieldOutput: degree must be an integer >= 0 or 'auto', got {degree!r}")
        if format == "xdmf" and degree not in (0, "auto"):
            raise ParameterError(
                f"FieldOutput: XDMF stores cell fields as DG0 only (degree {degree!r} asked); use format='vtx'"
            )
        self.folder = Path(folder)
        self.materials = materials
        self.fibres = fibres
        self.activation = activation
        self.format = format
        self.degree = degree
        self.times = times
        self.name = name
        self._cells: CellFunctions | None = None
        self._writers: list[Output] = []

    @property
    def cell_functions(self) -> dict:
        """Name → the cell-wise function written (after :meth:`start`; empty before)."""
        return {f.name: f for f in self._cells.functions} if self._cells is not None else {}

    def start(self, sim: Simulation) -> None:
        """Compile the expressions and open the files (checks the folder on every rank first)."""
        base = sim.fields.base
        cell_names = [n for n in self.names if n != "displacement"]
        expressions = cell_field_expressions(
            base, cell_names, self.materials, fibres=self.fibres, activation=self.activation
        )
        degree = self.degree
        if degree == "auto":
            degree = 0 if self.format == "xdmf" else max(0, base.degree - 1)
        assert isinstance(degree, int)  # __init__ accepts an integer or "auto"
        self._cells = CellFunctions(base.domain, expressions, degree) if expressions else None
        nodal = sim.fields.output() if "displacement" in self.names else []
        cells = self._cells.functions if self._cells is not None else []
        times = None if self.times is None else list(self.times)
        if self.format == "xdmf":
            both = [*nodal, *cells]
            self._writers = [XDMF(self.folder / f"{self.name}.xdmf", both, times=times, role=self.name)] if both else []
        else:
            self._writers = []
            if nodal:
                self._writers.append(VTX(self.folder / f"{self.name}.bp", nodal, times=times, role=self.name))
            if cells:
                role = f"{self.name}_cells"
                self._writers.append(VTX(self.folder / f"{role}.bp", cells, times=times, role=role))
        for writer in self._writers:
            writer.start(sim)

    def write(self, sim: Simulation, step: StepRecord | None) -> None:
        """Refresh the cell fields and write the frames that are due."""
        if self._cells is not None:
            self._cells.refresh()
        for writer in self._writers:
            writer.write(sim, step)

    def close(self, sim: Simulation) -> None:
        """Close the files."""
        for writer in self._writers:
            writer.close(sim)

    def state(self, sim: Simulation) -> dict:
        """The writers' states (remaining output times, files so far)."""
        return {"writers": [w.state(sim) for w in self._writers]}

    def restart(self, sim: Simulation, state: dict | None) -> None:
        """Continue the writers (their first frame: the restart state)."""
        if self._cells is not None:
            self._cells.refresh()
        saved = (state or {}).get("writers", [])
        for k, writer in enumerate(self._writers):
            writer.restart(sim, saved[k] if k < len(saved) else None)

    def summary(self, sim: Simulation, summary: dict) -> dict:
        """The files of a restarted run, per writer."""
        out = {}
        for writer in self._writers:
            out.update(writer.summary(sim, summary))
        return out
