r"""The contact forces and gaps as fields for ParaView: nodal force, traction and gap of every contact, a VTX series.

:class:`ContactField` writes, at the initial state and after every step, two
vector fields of the displacement's space and a scalar one of its scalar space:

* ``contact_force`` — the force every contact (barrier and friction, or tie)
  exerts on each node, :math:`f_a = -\partial E/\partial x_a` summed over the
  contacts, in N;
* ``contact_traction`` — :math:`t_a = f_a / A_a`, the force per reference area,
  with :math:`A_a = \int_\Gamma \phi_a\,dA` the lumped area of node :math:`a`
  over the contacts' boundary groups (zero where :math:`A_a = 0`), in Pa: the
  contact pressure is its normal component, the friction stress the rest;
* ``contact_gap`` — the gap :math:`g_a`, in m, the smallest over the contacts of:
  for a rigid obstacle (plane, sphere, cylinder) the signed distance of every
  node of the body from it where it is now (the contact nodes' :math:`d_a`,
  positive outside, so about :math:`\hat d` or less where the body touches
  and the distance to the obstacle away from it); for mesh contact (self,
  pair, tool) the smallest distance of the primitive pairs closer than
  :math:`\hat d` a surface node belongs to (through a collision proxy: the pairs
  of the proxy vertices its shape function takes part in), and :math:`\hat d` where it
  belongs to none, as at every other node (out of reach: a gap belongs to a
  pair of primitives, so away from contact it is capped there). A tie measures no gap: 0 where only
  ties act.

The forces are those the outputs sum (``<name>_force``), node by node: the
two force fields' integrals are the recorded totals.

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
        scalar, sub_map = space.sub(0).collapse()
        bs = space.dofmap.index_map_bs
        block = np.asarray(sub_map, dtype=np.int64).reshape(-1) // bs  # scalar dof -> the node's block (0.11: a list)
        self._block_to_scalar = np.full(self.force.x.array.size // bs, -1, dtype=np.int64)
        self._block_to_scalar[block] = np.arange(len(block))
        self._scalar_blocks = block
        self._points = scalar.tabulate_dof_coordinates()[:, : problem.domain.gdim]
        self.gap = fem.Function(scalar, name="contact_gap")
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
        super().__init__(path, [self.force, self.traction, self.gap], times=times, role="contact_vtx")

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
        self._refresh_gap(u)

    def _refresh_gap(self, u: np.ndarray) -> None:
        """The gaps at the current state (module docstring); collective (mesh contact evaluates its pairs)."""
        gdim = self._points.shape[1]
        bs = self.force.function_space.dofmap.index_map_bs
        rows = self._scalar_blocks[:, None] * bs + np.arange(gdim)
        x = self._points + u[self._parent[rows]]  # every node where it is now
        gap = np.full(len(x), np.inf)
        for barrier in self.barriers:
            obstacle = getattr(barrier, "obstacle", None)
            if obstacle is not None:
                gap = np.minimum(gap, obstacle.signed_distance(x, barrier.time))
            elif hasattr(barrier, "pair_gaps"):
                dofs, values = barrier.pair_gaps(u)
                mine = np.full(len(x), float(barrier.dhat))
                scalar = self._block_to_scalar[self._to_collapsed[np.asarray(dofs)[:, 0]] // bs]
                mine[scalar] = values
                gap = np.minimum(gap, mine)
        self.gap.x.array[:] = np.where(np.isfinite(gap), gap, 0.0)
        self.gap.x.scatter_forward()
