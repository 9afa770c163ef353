"""Case → objects: the mesh, materials, loads, conditions, problem, solver, stepping and the Simulation.

:func:`build` calls the statements of :func:`hyperfem.app.plan.plan` — the ones
``hyperfem run --print-python`` prints — one by one
(:func:`hyperfem.app.calls.evaluate`: each constructor called with the values of
the earlier statements), on every rank. So ``hyperfem run`` builds exactly the
objects of that script (:class:`~hyperfem.HyperelasticProblem` or
:class:`~hyperfem.problem.MixedHyperelasticProblem`, an
:class:`~hyperfem.dynamics.IncrementalProblem` for a dynamic run, the
:class:`~hyperfem.NewtonSolver`, the stepping preset and the
:class:`~hyperfem.simulation.Simulation` with its outputs): one code path, and
no source text is run.

Between reading the mesh and building anything on it, :func:`check_mesh`
checks every physical-group name of the case against the mesh (with a
did-you-mean and the names that exist) and the orientation of the cells
(:mod:`hyperfem.mesh.orientation`). A hyperfem error raised while building an
entry comes back as a :class:`~hyperfem.app.schema.CaseFileError` naming the
case key (``bc[0]: ...``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from mpi4py import MPI

from hyperfem.app.calls import evaluate
from hyperfem.app.plan import Statement, plan
from hyperfem.app.report import say, warn
from hyperfem.app.schema import CaseFileError, suggestion
from hyperfem.app.spec import Case
from hyperfem.errors import HyperfemError, MeshError
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.orientation import domain_orientation
from hyperfem.problem.protocol import SolidProblem
from hyperfem.simulation.outputs import Output
from hyperfem.stability.run import BucklingRun
from hyperfem.simulation.runner import Simulation
from hyperfem.solver.newton import NewtonSolver

__all__ = ["Built", "build", "build_domain", "check_dimensions", "check_groups", "check_mesh"]


@dataclass
class Built:
    """The objects of a case, by the names of the printed script.

    Attributes:
        case: The case.
        domain: The mesh and its named groups.
        material: The energy of the body: one energy, or region name → energy (``materials`` of the script).
        problem: The problem the solver solves (for a dynamic run: its time step).
        solver: The Newton solver.
        stepping: The load or time stepping.
        outputs: The observers of the run (none for a buckling analysis).
        simulation: The run (a :class:`~hyperfem.stability.run.BucklingRun` for ``type = "buckling"``).
        variables: Every variable of the script, the above included (``materials``/``material``,
            ``params``, ``bcs``, ``loads``, ``fibres``, ``base``, ...).
    """

    case: Case
    domain: Domain
    material: Any
    problem: SolidProblem
    solver: NewtonSolver
    stepping: Any
    outputs: list[Output]
    simulation: Simulation | BucklingRun
    variables: dict[str, Any] = field(default_factory=dict)


def _groups(case: Case) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """``(key, name)`` of every facet group and every cell group the case names."""
    facets = [(f"{bc.key}.boundary", bc.boundary) for bc in case.bcs]
    facets += [(f"{ld.key}.boundary", ld.boundary) for ld in case.loads if ld.boundary is not None]
    for c in case.contacts:
        if c.boundary is not None:
            facets.append((f"{c.key}.boundary", c.boundary))
        facets += [(f"{c.key}.boundaries[{i}]", name) for i, name in enumerate(c.boundaries or ())]
    for key, fibres in (("fibres", case.fibres), ("second_fibres", case.second_fibres)):
        if fibres is not None and fibres.type == "laplace":
            facets += [(f"{key}.source", fibres.options["source"]), (f"{key}.target", fibres.options["target"])]
    cells = [(f"{m.key}.region", m.region) for m in case.materials if m.region is not None]
    cells += [(f"{ld.key}.region", ld.region) for ld in case.loads if ld.region is not None]
    return facets, cells


def check_groups(case: Case, domain: Domain) -> None:
    """Every boundary and region the case names must be a physical group of the mesh.

    Raises:
        CaseFileError: ``bc[0].boundary: no boundary 'x' in MESH (did you mean 'y'?); boundaries: ...``.
    """
    facets, cells = _groups(case)
    for kind, entries, groups in (("boundary", facets, domain.facet_groups), ("region", cells, domain.cell_groups)):
        for key, name in entries:
            if name not in groups:
                available = ", ".join(sorted(groups)) or "none"
                raise CaseFileError(
                    f"{key}: no {kind} {name!r} in {domain.source}{suggestion(name, groups)}; "
                    f"{kind} groups of the mesh: {available}",
                    case.source,
                )


def check_dimensions(case: Case, domain: Domain) -> None:
    """Vectors of the case must have one entry per displacement component of the mesh.

    Raises:
        CaseFileError: A boundary value, load, affine field or fibre direction of the wrong length.
    """
    gdim = domain.gdim

    def fail(key: str, what: str) -> None:
        raise CaseFileError(f"{key}: {what} (the mesh {domain.source} has {gdim} displacement components)", case.source)

    for bc in case.bcs:
        if bc.type == "displacement" and bc.components is None and bc.value is not None and len(bc.value) != gdim:
            fail(f"{bc.key}.value", f"{len(bc.value)} values; give {gdim}, or components = [...] to prescribe fewer")
        if bc.components is not None and max(bc.components) >= gdim:
            fail(f"{bc.key}.components", f"component {max(bc.components)} does not exist")
        if bc.type == "rotation" and gdim != 3:
            fail(bc.key, "a rotation needs a 3D mesh")
    for load in case.loads:
        if isinstance(load.value, Mapping):
            if len(load.value["matrix"]) != gdim:
                fail(f"{load.key}.value.matrix", f"a {len(load.value['matrix'])}x{len(load.value['matrix'])} matrix")
        elif isinstance(load.value, tuple) and len(load.value) != gdim:
            fail(f"{load.key}.value", f"{len(load.value)} components")
    for contact in case.contacts:
        in_2d = ("self", "pair", "tie", "tool")
        if contact.boundaries is not None and gdim != 3 and not (gdim == 2 and contact.type in in_2d):
            fail(contact.key, f"a {contact.type} contact needs a 3D mesh of tetrahedra or hexahedra"
                 + (" (in 2D: self, pair, tie and tool contacts)" if gdim == 2 else ""))
        for key in ("motion", "offset"):
            value = getattr(contact, key) if contact.type == "tool" else None
            if value is not None and len(value) != gdim:
                fail(f"{contact.key}.{key}", f"{len(value)} components")
        if contact.path is not None and len(contact.path.points[0]) != gdim:
            fail(f"{contact.key}.path.points", f"rows of {len(contact.path.points[0])} components")
        name, where = ("center", contact.center) if contact.type == "sphere" else ("point", contact.point)
        if where is not None and len(where) != gdim:
            fail(f"{contact.key}.{name}", f"{len(where)} components")
    for key, fibres in (("fibres", case.fibres), ("second_fibres", case.second_fibres)):
        if fibres is not None and fibres.type == "constant" and len(fibres.options["direction"]) != gdim:
            fail(f"{key}.direction", f"{len(fibres.options['direction'])} components")


def check_mesh(case: Case, domain: Domain, *, echo: bool = False) -> None:
    """Group names (:func:`check_groups`), vector lengths (:func:`check_dimensions`) and cell orientation (collective).

    Args:
        case: The case.
        domain: Its mesh.
        echo: Print the mesh line and warnings on rank 0.

    Raises:
        CaseFileError: A group the case names is not in the mesh, or a vector of the wrong length.
        MeshError: The mesh has cells without volume.
    """
    check_groups(case, domain)
    check_dimensions(case, domain)
    counts = domain_orientation(domain)
    if counts is None:
        return
    if counts.degenerate:
        raise MeshError(
            f"{domain.source}: {counts.degenerate} of {counts.cells} cells have no volume (degenerate); fix the mesh "
            "(hyperfem mesh-quality shows the measures)"
        )
    if counts.inverted and echo:
        warn(
            f"{domain.source}: {counts.inverted} of {counts.cells} cells are inverted (negative orientation); "
            "harmless here (hyperfem integrates |det J|), but other tools may refuse the file "
            "(hyperfem convert --reorient fixes it)",
            domain.comm,
        )


def _value(node: object, key: str, variables: dict, case: Case) -> object:
    """The value of one plan node; a hyperfem error comes back naming the case key (``bc[0]: ...``)."""
    try:
        return evaluate(node, variables)
    except CaseFileError:
        raise
    except HyperfemError as exc:
        raise CaseFileError(f"{key}: {exc}", case.source) from exc


def _run(statement: Statement, variables: dict, case: Case) -> object:
    if statement.items is None:
        return _value(statement.value, statement.key, variables, case)
    return [_value(node, key, variables, case) for key, node in statement.items]


def build(case: Case, comm: MPI.Comm = MPI.COMM_WORLD, *, echo: bool = False) -> Built:
    """Build every object of ``case`` (collective), ending with the ``simulation``.

    Args:
        case: The checked case.
        comm: Communicator of the run.
        echo: Print a line on the run and its mesh (rank 0) before building on the mesh.

    Raises:
        CaseFileError: A group name the mesh lacks, or a hyperfem error while building an entry (with its key).
        OutputError: The output folder cannot be written.
        MeshError: The mesh cannot be read, or has degenerate cells.
    """
    variables: dict[str, Any] = {"comm": comm}
    for statement in plan(case):
        value = _run(statement, variables, case)
        if statement.target is not None:
            variables[statement.target] = value
        if statement.target == "domain":
            assert isinstance(value, Domain)
            check_mesh(case, value, echo=echo)
            if echo:
                cells = value.mesh.topology.index_map(value.tdim).size_global
                kind = case.stepping.type
                say(f"{case.name} ({case.source}): {kind}, {comm.size} rank(s); mesh {value.source}: {cells} cells",
                    comm)
    names = ("domain", "problem", "solver", "stepping", "outputs", "simulation")
    material = variables["materials"] if "materials" in variables else variables["material"]
    found = {n: variables.get(n, []) if n == "outputs" else variables[n] for n in names}  # a buckling run has none
    return Built(case, material=material, **found, variables=variables)


def build_domain(case: Case, comm: MPI.Comm = MPI.COMM_WORLD) -> Domain:
    """Only the mesh of ``case`` (its ``domain`` statement; collective), e.g. to check the case."""
    variables: dict[str, Any] = {"comm": comm}
    for statement in plan(case):  # the domain and what it refers to (the case folder)
        if statement.target in ("case_dir", "domain"):
            variables[statement.target] = _run(statement, variables, case)
    return variables["domain"]
