r"""The contact forces as a field for ParaView: nodal force and traction of every contact, a VTX time series.

:class:`ContactField` writes, at the initial state and after every step, two
vector fields of the displacement's space:

* ``contact_force`` — the force every contact (barrier and friction, or tie)
  exerts on each node, :math:`f_a = -\partial E/\partial x_a` summed over the
  contacts, in N;
* ``contact_traction`` — :math:`t_a = f_a / A_a`, the force per reference area,
  with :math:`A_a = \int_\Gamma \phi_a\,dA` the lumped area of node :math:`a`
  over the contacts' boundary groups (zero where :math:`A_a = 0`), in Pa: the
  contact pressure is its normal component, the friction stress the rest.

The forces are those the outputs sum (``<name>_force``), node by node: the
two fields' integrals are the recorded totals. Gaps are not written: for
mesh contact they belong to primitive pairs, not nodes.

Example::

    outputs = [Recorder(contact), ContactField(out / "contact.bp", [contact])]
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import ufl
from dolfinx import fem
import dolfinx.fem.petsc as fpetsc
from petsc4py import PETSc

from hyperfem.problem.protocol import SolidProblem
from hyperfem.simulation.outputs import VTX

__all__ = ["ContactField"]


def _boundaries(barrier: Any) -> list[str]:
    """The boundary groups a contact acts on (plane/sphere/cylinder: one; surface, tool, tie: several)."""
    contact = barrier.contact
    if hasattr(contact, "boundaries"):
        return list(contact.boundaries)
    if hasattr(contact, "slave"):
        return [contact.slave, contact.master]
    return [contact.boundary]


class ContactField(VTX):
    """A VTX series of the contact force and traction of every contact (module docstring).

    Args:
        path: The ``.bp`` folder.
        barriers: The bound contacts (``PlaneContact(...).bind(problem)``, ...), on one problem.
        times: As for :class:`~hyperfem.simulation.outputs.VTX`.
    """

    def __init__(self, path: str | Path, barriers: Sequence[Any], *, times: Sequence[float] | None = None):
        self.barriers = list(barriers)
        problem: SolidProblem = self.barriers[0].problem
        self.problem = problem
        whole = problem.u.function_space
        if problem.displacement_space() is whole:  # all of u is displacement
            space, parent = whole, np.arange(problem.u.x.array.size)
        else:  # the (u, p, theta) problem: the collapsed displacement space
            space, collapse_map = problem.displacement_space().collapse()
            parent = np.asarray(collapse_map, dtype=np.int64).reshape(-1)  # 0.11: a list of one array
        self._parent = parent  # collapsed dof -> the unknown's local dof
        self._to_collapsed = np.full(problem.u.x.array.size, -1, dtype=np.int64)
        self._to_collapsed[self._parent] = np.arange(len(self._parent))
        self.force = fem.Function(space, name="contact_force")
        self.traction = fem.Function(space, name="contact_traction")
        groups = sorted({name for b in self.barriers for name in _boundaries(b)})
        domain = problem.domain
        v = ufl.TestFunction(space)
        ones = ufl.as_vector([1.0] * domain.gdim)
        terms = [ufl.inner(ones, v) * domain.ds(name) for name in groups]
        areas = fpetsc.assemble_vector(fem.form(sum(terms[1:], terms[0])))
        # The owners sum the shares of their nodes.
        areas.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type, unused-ignore]
        self._area = np.zeros(self.force.x.array.size)
        n = len(areas.array_r)
        self._area[:n] = areas.array_r
        areas.destroy()
        super().__init__(path, [self.force, self.traction], times=times, role="contact_vtx")

    def _refresh(self) -> None:
        """The forces and tractions at the current state."""
        u = self.problem.u.x.array
        force = np.zeros(self.force.x.array.size)
        for barrier in self.barriers:
            dofs, values = barrier.gradient(u)
            rows = self._to_collapsed[np.asarray(dofs).ravel()]
            np.add.at(force, rows, -np.asarray(values).ravel())
        self.force.x.array[:] = force
        self.force.x.scatter_forward()
        owned = self.force.function_space.dofmap.index_map.size_local * self.force.function_space.dofmap.index_map_bs
        traction = np.zeros_like(force)
        area = self._area[:owned]
        traction[:owned] = np.divide(force[:owned], area, out=np.zeros(owned), where=area > 0.0)
        self.traction.x.array[:] = traction
        self.traction.x.scatter_forward()
