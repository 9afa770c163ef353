r"""Contact: bodies that touch rigid obstacles, intersection-free, as one more term of the energy.

The total potential becomes :math:`\Pi(u) = \Pi_\text{elastic}(u) - W_\text{ext}(u) + \kappa B(x(u))`,
:math:`B` the barrier of Incremental Potential Contact (Li et al. 2020) over the
distances between the contact nodes and the obstacle. This first slice of
issue 19: a rigid plane (half-space) or sphere with a prescribed translation, frictionless.

* :class:`PlaneContact` — the contact (boundary, plane, :math:`\hat d`,
  :math:`\kappa`); ``.bind(problem)`` gives the :class:`PlaneBarrier`, passed to
  ``NewtonSolver(problem, external_energies=[...])`` and read by outputs
  (``Recorder(barrier)``);
* :mod:`~hyperfem.contact.barrier` — the IPC barrier from ``ipctk`` (the
  optional extra ``hyperfem[contact]``);
* :mod:`~hyperfem.contact.ccd` — the collision-free step filter;
* :mod:`~hyperfem.contact.obstacles`, :mod:`~hyperfem.contact.nodes`,
  :mod:`~hyperfem.contact.defaults` — the plane, the contact nodes, the default
  :math:`\hat d` and :math:`\kappa`.

Importing this package does not import ``ipctk``; constructing a contact
without it raises a one-line :class:`~hyperfem.errors.ParameterError`.
"""

from hyperfem.contact.bodies import SurfaceContact, surface_defaults
from hyperfem.contact.barrier import CONTACT_EXTRA, barrier, barrier_derivatives, require_ipctk
from hyperfem.contact.ccd import (
    CCD_SAFETY,
    PlaneCollisionFilter,
    SphereCollisionFilter,
    plane_step_fraction,
    sphere_step_fraction,
)
from hyperfem.contact.defaults import DHAT_FRACTION, STIFFNESS_FACTOR, default_dhat, default_stiffness
from hyperfem.contact.nodes import BoundaryNodes, boundary_nodes, facet_size
from hyperfem.contact.nodal import NodalBarrier
from hyperfem.contact.mesh_barrier import MeshBarrier, MeshCollisionFilter, RigidSurface
from hyperfem.contact.surface import ContactSurface, contact_surface
from hyperfem.contact.shapes import icosphere
from hyperfem.contact.tool import ToolContact, read_tool_surface
from hyperfem.contact.obstacles import Ball, HalfSpace
from hyperfem.contact.plane import PlaneBarrier, PlaneContact
from hyperfem.contact.sphere import SphereBarrier, SphereContact, project_psd

__all__ = [
    "CCD_SAFETY",
    "CONTACT_EXTRA",
    "DHAT_FRACTION",
    "STIFFNESS_FACTOR",
    "Ball",
    "BoundaryNodes",
    "ContactSurface",
    "MeshBarrier",
    "MeshCollisionFilter",
    "RigidSurface",
    "SurfaceContact",
    "ToolContact",
    "read_tool_surface",
    "contact_surface",
    "surface_defaults",
    "HalfSpace",
    "NodalBarrier",
    "PlaneBarrier",
    "PlaneCollisionFilter",
    "PlaneContact",
    "SphereBarrier",
    "SphereCollisionFilter",
    "SphereContact",
    "barrier",
    "barrier_derivatives",
    "boundary_nodes",
    "default_dhat",
    "default_stiffness",
    "facet_size",
    "icosphere",
    "plane_step_fraction",
    "project_psd",
    "require_ipctk",
    "sphere_step_fraction",
]
