r"""Contact between the surfaces of deformable bodies: self-contact and two bodies, intersection-free.

:class:`SurfaceContact` names one or more boundary groups; every triangle and
edge of them may touch every other one (of the same group — self-contact —
or of another group) except the primitives that share a node; in 2D the
boundary edges (segments) of the groups. Its
:meth:`~SurfaceContact.bind` gives a :class:`~hyperfem.contact.mesh_barrier.MeshBarrier`,
the IPC barrier of the primitive pairs from ``ipctk``, an
:class:`~hyperfem.solver.external.ExternalEnergy` of
:class:`~hyperfem.solver.NewtonSolver`.

**Two bodies are one mesh with several cell groups** (e.g. gmsh physical
volumes ``lower`` and ``upper`` meshed separately, with non-matching facets
where they meet), not several meshes: a DOLFINx problem lives on one mesh,
so one function space, one SNES vector, one tangent and one MPI
distribution hold both bodies, the materials refer to the cell groups
(``[[material]] region = ...``) and the boundary conditions to the facet
groups as for one body; nothing in the solver has to know that there are
two. Two meshes would need a block system and a second distribution for
no gain. :func:`hyperfem.mesh.stacked_blocks_mesh` makes such a mesh.

A pair contact (``boundaries = [a, b]``) lets the primitives of ``a`` and
``b`` touch each other *and* themselves: a body that folds onto itself must
not pass through itself either. Its force output is the force on ``a``.

Example::

    contact = hf.contact.SurfaceContact(["lower_top", "upper_bottom"], dhat=1e-3).bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[contact])
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hyperfem.contact.ccd import CCD_SAFETY
from hyperfem.contact.defaults import DHAT_FRACTION, STIFFNESS_FACTOR, mean_tangent_diagonal
from hyperfem.contact.mesh_barrier import MeshBarrier
from hyperfem.contact.nodes import facet_size
from hyperfem.contact.settings import check_boundaries, check_contact_settings, check_subdivision
from hyperfem.contact.surface import ContactSurface, contact_surface
from hyperfem.loading.profiles import linear_profile
from hyperfem.problem.protocol import SolidProblem

__all__ = ["SurfaceContact", "surface_defaults"]


def surface_defaults(
    problem: SolidProblem, boundaries: Sequence[str], surface: ContactSurface, dhat: float | None,
    stiffness: float | None
) -> tuple[float, float]:
    r"""The barrier width and ``ipctk`` stiffness of a mesh contact: the given ones, or the defaults (collective).

    :math:`\hat d` = :data:`~hyperfem.contact.defaults.DHAT_FRACTION` times the smallest mean facet size
    of the groups; :math:`\kappa = \bar k/(2\hat d^2)` with :math:`\bar k` the mean tangent diagonal at the
    surface nodes (:mod:`~hyperfem.contact.mesh_barrier` says why), times nodes per collision vertex where a
    collision proxy has more vertices than nodes (:mod:`~hyperfem.contact.proxy`): the same pressure at the
    same gap with or without one.
    """
    if dhat is None:
        dhat = DHAT_FRACTION * min(facet_size(problem.domain, name) for name in boundaries)
    if stiffness is None:
        dofs = surface.dofs
        k = mean_tangent_diagonal(problem, dofs, np.full(dofs.shape[1], 1.0 / dofs.shape[1]))
        stiffness = STIFFNESS_FACTOR * k / (2.0 * dhat * dhat) * surface.size / surface.collision_size
    return float(dhat), float(stiffness)


@dataclass(frozen=True)
class SurfaceContact:
    r"""Intersection-free contact of boundary surfaces with each other and themselves (module docstring).

    Attributes:
        boundaries: The boundary groups whose triangles may touch (one: self-contact; two: a pair).
        dhat: Barrier width :math:`\hat d > 0` (``None``: 1 % of the smallest mean facet size).
        stiffness: ``ipctk``'s barrier stiffness :math:`\kappa > 0`, on squared distances (``None``: the
            default of :func:`surface_defaults`; fixed for the run).
        safety: The collision filter's :math:`s \in (0, 1)`.
        friction: Coulomb coefficient :math:`\mu \ge 0` (0: frictionless), smoothed and lagged per step
            as in IPC (``ipctk``'s tangential collisions and friction potential; :mod:`~hyperfem.contact.mesh_barrier`).
        friction_epsilon: The slip length :math:`\epsilon > 0` below which a pair sticks elastically
            (``None``: :math:`0.1\,\hat d`).
        name: Prefix of the output columns (``contact_force``, ...).
        subdivision: 1: the barrier acts on the facets' nodes; :math:`s > 1`: on a finer collision proxy whose
            vertices follow the facets' shape functions (a facet edge in ``degree * s`` segments;
            :mod:`~hyperfem.contact.proxy`), for P2/Q2 surfaces (a uniform pressure's consistent nodal loads
            differ between their nodes: none at a P2 triangle's corners) and Q1 faces. ``None``:
            :func:`~hyperfem.contact.proxy.default_subdivision` (2 for degree 2 and hexahedra, else 1).

    Raises:
        ParameterError: A bad entry (one line), no boundary, a boundary named twice,
            or ``ipctk`` not installed.
    """

    boundaries: Sequence[str]
    dhat: float | None = None
    stiffness: float | None = None
    safety: float = CCD_SAFETY
    name: str = "contact"
    friction: float = 0.0
    friction_epsilon: float | None = None
    subdivision: int | None = None

    def __post_init__(self) -> None:
        names, where = check_boundaries(self.boundaries, "SurfaceContact")
        object.__setattr__(self, "boundaries", tuple(names))
        check_subdivision(self.subdivision, where)
        check_contact_settings(
            where, dhat=self.dhat, stiffness=self.stiffness, safety=self.safety, friction=self.friction,
            friction_epsilon=self.friction_epsilon, profile=linear_profile, name=self.name,
        )

    @property
    def where(self) -> str:
        """The contact, for messages."""
        return f"SurfaceContact on {list(self.boundaries)!r}"

    def bind(self, problem: SolidProblem) -> MeshBarrier:
        """The barrier of this contact on ``problem`` (collective).

        Raises:
            UnknownGroupError: A boundary group does not exist (the message lists them).
            ParameterError: Not a degree-1/2 problem on tetrahedra or hexahedra (3D) or triangles or quadrilaterals
                (2D), or the surfaces start touching or intersecting (the message says where).
        """
        surface = contact_surface(problem, self.boundaries, self.where, self.subdivision)
        dhat, stiffness = surface_defaults(problem, self.boundaries, surface, self.dhat, self.stiffness)
        return MeshBarrier(
            self, problem, surface, where=self.where, dhat=dhat, stiffness=stiffness, safety=self.safety,
            friction=self.friction, friction_epsilon=self.friction_epsilon
        )
