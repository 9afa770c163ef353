r"""Contact of a body with a rigid infinite cylinder (a roller, a rod, a retractor bar): the IPC barrier of its nodes.

:class:`CylinderContact` names the boundary that may touch and the cylinder
(:class:`~hyperfem.contact.obstacles.Cylinder`: a point of its axis, the axis
direction :math:`a`, the radius, an optional translation). With
:math:`P = I - a a^T`, :math:`q_a = P(x_a - c)`, :math:`r_a = |q_a|` and
:math:`n_a = q_a / r_a`,

.. math::
    d_a = r_a - R, \qquad \nabla d_a = n_a, \qquad \nabla^2 d_a = \frac{P - n_a n_a^T}{r_a},

the sphere's formulas (:mod:`~hyperfem.contact.sphere`) in the plane normal to
the axis: the barrier's Hessian block
:math:`\kappa(b'' n n^T + b' (P - n n^T)/r)` is indefinite and the tangent
gets its PSD projection; the collision filter is the sphere's quadratic on
the projected offsets and steps. Friction, outputs and MPI as for the plane
and the sphere (:mod:`~hyperfem.contact.nodal`). The cylinder has no ends.

Example::

    roller = hf.contact.CylinderContact("top", point=(0.5, 0, 1.2), axis=(0, 1, 0), radius=0.2,
                                        motion=(0, 0, -0.3)).bind(problem)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hyperfem.contact.ccd import CCD_SAFETY, SphereCollisionFilter
from hyperfem.contact.defaults import default_dhat, default_stiffness
from hyperfem.contact.nodal import NodalBarrier
from hyperfem.contact.nodes import boundary_nodes
from hyperfem.contact.obstacles import Cylinder
from hyperfem.contact.settings import check_contact_settings
from hyperfem.contact.sphere import project_psd
from hyperfem.errors import ParameterError
from hyperfem.loading.profiles import linear_profile
from hyperfem.problem.protocol import SolidProblem
from hyperfem.validation import check_name

__all__ = ["CylinderBarrier", "CylinderContact"]


@dataclass(frozen=True)
class CylinderContact:
    r"""Intersection-free contact (optional friction) of a boundary with a rigid infinite cylinder (module docstring).

    Attributes:
        boundary: The boundary group whose nodes may touch the cylinder.
        point: A point of the axis (at ``profile(t) = 0``).
        axis: The axis direction (3 components, any length > 0).
        radius: :math:`R > 0`.
        dhat: Barrier width :math:`\hat d > 0` (``None``: :func:`~hyperfem.contact.defaults.default_dhat`).
        stiffness: Barrier stiffness :math:`\kappa > 0` (``None``: the mean tangent diagonal at the contact nodes).
        motion: A translation of the cylinder, scaled by ``profile(t)`` (``None``: it stays).
        profile: :math:`f(t)` of the translation (default: the load factor).
        safety: The collision filter's :math:`s \in (0, 1)`.
        name: Prefix of the output columns (``contact_force``, ...).
        friction: Coulomb coefficient :math:`\mu \ge 0` (0: frictionless), smoothed and lagged per step.
        friction_epsilon: The slip length below which a node sticks elastically (``None``: :math:`0.1\,\hat d`).

    Raises:
        ParameterError: A bad entry (one line), or ``ipctk`` is not installed.
    """

    boundary: str
    point: Sequence[float]
    axis: Sequence[float]
    radius: float
    dhat: float | None = None
    stiffness: float | None = None
    motion: Sequence[float] | None = None
    profile: Callable[[float], float] = linear_profile
    safety: float = CCD_SAFETY
    name: str = "contact"
    friction: float = 0.0
    friction_epsilon: float | None = None

    def __post_init__(self) -> None:
        check_name(self.boundary, "boundary", "CylinderContact")
        where = f"CylinderContact on {self.boundary!r}"
        try:
            cylinder = Cylinder(self.point, self.axis, self.radius, self.motion)
        except ParameterError as exc:
            raise ParameterError(f"{where}: {str(exc).removeprefix('Cylinder: ')}") from None
        object.__setattr__(self, "point", cylinder.point)
        object.__setattr__(self, "axis", cylinder.axis)
        object.__setattr__(self, "radius", cylinder.radius)
        object.__setattr__(self, "motion", cylinder.motion)
        check_contact_settings(
            where, dhat=self.dhat, stiffness=self.stiffness, safety=self.safety, friction=self.friction,
            friction_epsilon=self.friction_epsilon, profile=self.profile, name=self.name,
        )

    @property
    def obstacle(self) -> Cylinder:
        """The cylinder as a :class:`~hyperfem.contact.obstacles.Cylinder`."""
        return Cylinder(self.point, self.axis, self.radius, self.motion, self.profile)

    def bind(self, problem: SolidProblem) -> CylinderBarrier:
        """The barrier of this contact on ``problem`` (collective).

        Raises:
            UnknownGroupError: ``boundary`` is not a boundary group of the mesh (the message lists them).
            ParameterError: The mesh is not 3D, or a node starts on or inside the cylinder.
        """
        return CylinderBarrier(self, problem)


class CylinderBarrier(NodalBarrier):
    r"""The barrier term :math:`\kappa B(u)` of a :class:`CylinderContact` on a problem (module docstring).

    Attributes:
        dhat: :math:`\hat d`.
        stiffness: :math:`\kappa`.
        nodes: The owned contact nodes.
        step_filter: The collision filter.
        time: The time (load factor) the cylinder is at.
    """

    behind = "on or inside the cylinder"

    def __init__(self, contact: CylinderContact, problem: SolidProblem):
        self.contact = contact
        self.where = f"CylinderContact on {contact.boundary!r}"
        self.problem = problem
        self.comm = problem.domain.comm
        self.obstacle = contact.obstacle
        if problem.domain.gdim != 3:
            raise ParameterError(f"{self.where}: a cylinder needs a 3D mesh, got {problem.domain.gdim}D")
        self.radius = float(contact.radius)
        self.projector = self.obstacle.projector
        self.nodes = boundary_nodes(problem, contact.boundary)
        self.dhat = contact.dhat if contact.dhat is not None else default_dhat(problem, contact.boundary)
        self.update(problem.time)
        self._check_start("cylinder")
        mean = np.full(3, 1.0 / np.sqrt(3.0))
        self.stiffness = (
            contact.stiffness if contact.stiffness is not None else default_stiffness(problem, self.nodes, mean)
        )
        self._init_friction(contact)
        self.step_filter = SphereCollisionFilter(
            self.nodes.dofs, self.nodes.X, lambda: self._center, self.radius, contact.safety, self.projector
        )

    # -- the ExternalEnergy contract ----------------------------------------
    def update(self, t: float) -> None:
        """Move the cylinder to time (load factor) ``t``."""
        self.time = float(t)
        self._center = self.obstacle.origin(t)
        self._refresh_lag()

    def _offsets(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:math:`q_a = P(x_a - c)` and :math:`r_a = |q_a|` of the owned nodes."""
        q = (self.nodes.positions(u) - self._center) @ self.projector
        return q, np.linalg.norm(q, axis=1)

    def distances(self, u: np.ndarray) -> np.ndarray:
        """Signed distances :math:`d_a = |P(x_a - c)| - R` of the owned nodes."""
        return self._offsets(u)[1] - self.radius

    def normals(self, u: np.ndarray) -> np.ndarray:
        """The outward unit vectors :math:`n_a = q_a / r_a` (normal to the axis)."""
        q, r = self._offsets(u)
        return q / r[:, None]

    def _barrier_gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`\kappa b'(d_a)\,n_a` at the active nodes: ``(dofs, values)``."""
        rows, first, _ = self._active(u)
        return self.nodes.dofs[rows], self.stiffness * first[:, None] * self.normals(u)[rows]

    def _barrier_hessian(self, u: np.ndarray, project: bool = True) -> tuple[np.ndarray, np.ndarray]:
        r"""The blocks :math:`\kappa(b'' n n^T + b'(P - n n^T)/r)` at the active nodes, PSD-projected by default."""
        rows, first, second = self._active(u)
        q, r = self._offsets(u)
        n = q[rows] / r[rows, None]
        outer = np.einsum("mi,mj->mij", n, n)
        tangential = (self.projector[None, :, :] - outer) / r[rows, None, None]
        blocks = self.stiffness * (second[:, None, None] * outer + first[:, None, None] * tangential)
        return self.nodes.dofs[rows], project_psd(blocks) if project else blocks
