r"""Contact: bodies that touch obstacles, tools, each other and themselves, intersection-free, in the one energy.

The total potential becomes :math:`\Pi(u) = \Pi_\text{elastic}(u) - W_\text{ext}(u) + \kappa B(x(u))`,
:math:`B` the barrier of Incremental Potential Contact (Li et al. 2020) over
the distances closer than :math:`\hat d`. Each contact's ``.bind(problem)``
gives an :class:`~hyperfem.solver.external.ExternalEnergy` passed to
``NewtonSolver(problem, external_energies=[...])`` and read by outputs
(``Recorder(barrier)``).

* Analytic rigid obstacles, per node (no gathering): :class:`PlaneContact`
  (a half-space), :class:`SphereContact` and :class:`CylinderContact`
  (:mod:`~hyperfem.contact.cylinder`), with a prescribed translation
  (each also a rotation, :class:`~hyperfem.loading.RigidRotation`)
  and smoothed Coulomb friction (:mod:`~hyperfem.contact.nodal`,
  :mod:`~hyperfem.contact.plane`, :mod:`~hyperfem.contact.sphere`,
  :mod:`~hyperfem.contact.ccd`, :mod:`~hyperfem.contact.obstacles`).
* Between surface triangles, from ``ipctk`` (:mod:`~hyperfem.contact.mesh_barrier`,
  the surface gathered by :mod:`~hyperfem.contact.surface`, degree-2 facets and hexahedral
  faces through the collision proxy of :mod:`~hyperfem.contact.proxy`):
  :class:`SurfaceContact` (self-contact, two bodies of one mesh;
  :mod:`~hyperfem.contact.bodies`) and :class:`ToolContact` (a rigid
  triangulated tool from an STL/OBJ/gmsh file or arrays, moving on a path and turning;
  :mod:`~hyperfem.contact.tool`, shapes in :mod:`~hyperfem.contact.shapes`). In 2D
  (plane strain, triangles or quadrilaterals) between boundary segments, a tool a polyline.
* Gluing: :class:`TieContact` (two groups of non-matching meshes held
  together by a two-pass penalty tie, in 2D along boundary segments; :mod:`~hyperfem.contact.tie`).
* :class:`ContactField` (:mod:`~hyperfem.contact.field`): the nodal contact
  force, traction and gap of every contact as a VTX series for ParaView.
* Under generalized-:math:`\alpha` the contact force is interpolated between
  the ends of a step like the internal forces (:class:`ForceInterpolation`,
  :mod:`~hyperfem.contact.interpolation`).
* :mod:`~hyperfem.contact.barrier` (the nodal barrier function),
  :mod:`~hyperfem.contact.defaults` (:math:`\hat d`, :math:`\kappa`),
  :mod:`~hyperfem.contact.nodes` (contact nodes), :mod:`~hyperfem.contact.settings`
  (the shared checks).

An obstacle pushed into a body that already touches it is handled by the
solver's predictor, which carries the overrun nodes with it
(:meth:`~hyperfem.solver.external.ExternalTerms.carry`).

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
from hyperfem.contact.cylinder import CylinderBarrier, CylinderContact
from hyperfem.contact.field import ContactField
from hyperfem.contact.interpolation import ForceInterpolation
from hyperfem.contact.defaults import DHAT_FRACTION, STIFFNESS_FACTOR, default_dhat, default_stiffness
from hyperfem.contact.nodes import BoundaryNodes, boundary_nodes, facet_size
from hyperfem.contact.nodal import NodalBarrier
from hyperfem.contact.mesh_barrier import MeshBarrier, MeshCollisionFilter, RigidSurface
from hyperfem.contact.surface import ContactSurface, contact_surface
from hyperfem.contact.shapes import icosphere
from hyperfem.contact.tie import TIE_FACTOR, TieBarrier, TieContact
from hyperfem.contact.tool import ToolContact, read_tool_surface
from hyperfem.contact.obstacles import Ball, Cylinder, HalfSpace
from hyperfem.contact.plane import PlaneBarrier, PlaneContact
from hyperfem.contact.sphere import SphereBarrier, SphereContact, project_psd

__all__ = [
    "CCD_SAFETY",
    "CONTACT_EXTRA",
    "DHAT_FRACTION",
    "STIFFNESS_FACTOR",
    "Ball",
    "BoundaryNodes",
    "ContactField",
    "ContactSurface",
    "Cylinder",
    "ForceInterpolation",
    "CylinderBarrier",
    "CylinderContact",
    "MeshBarrier",
    "MeshCollisionFilter",
    "RigidSurface",
    "SurfaceContact",
    "TIE_FACTOR",
    "TieBarrier",
    "TieContact",
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
