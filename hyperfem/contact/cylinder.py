r"""Contact of a body with a rigid infinite cylinder (a roller, a rod, a retractor bar): the IPC barrier of its nodes.

:class:`CylinderContact` names the boundary that may touch and the cylinder
(:class:`~hyperfem.contact.obstacles.Cylinder`: a point of its axis, the axis
direction :math:`a`, the radius, an optional translation and rotation, which
turns the axis: :math:`a(t) = R(t)a_0`, :mod:`~hyperfem.contact.obstacles`). With
:math:`P = I - a a^T`, :math:`q_a = P(x_a - c)`, :math:`r_a = |q_a|` and
:math:`n_a = q_a / r_a`,

.. math::
    d_a = r_a - R, \qquad \nabla d_a = n_a, \qquad \nabla^2 d_a = \frac{P - n_a n_a^T}{r_a},

the sphere's formulas (:mod:`~hyperfem.contact.sphere`) in the plane normal to
the axis: the barrier's Hessian block
:math:`\kappa(b'' n n^T + b' (P - n n^T)/r)` is indefinite and the tangent
gets its PSD projection while the nodes move, the exact blocks once they
settle, as the sphere's; the collision filter is the sphere's quadratic on
the projected offsets and steps. Friction, outputs and MPI as for the plane
and the sphere (:mod:`~hyperfem.contact.nodal`). The cylinder has no ends.

Example::

    roller = hf.contact.CylinderContact("top", point=(0.5, 0, 1.2), axis=(0, 1, 0), radius=0.2,
                                        motion=(0, 0, -0.3)).bind(problem)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from hyperfem.contact.ccd import CCD_SAFETY
from hyperfem.contact.obstacles import Cylinder, Motion
from hyperfem.contact.settings import check_contact_settings
from hyperfem.contact.sphere import SphereBarrier
from hyperfem.errors import ParameterError
from hyperfem.loading.motion import RigidRotation
from hyperfem.loading.profiles import linear_profile
from hyperfem.problem.protocol import SolidProblem
from hyperfem.validation import check_name

__all__ = ["CylinderBarrier", "CylinderContact"]


@dataclass(frozen=True)
class CylinderContact:
    r"""Intersection-free contact (optional friction) of a boundary with a rigid infinite cylinder (module docstring).

    Attributes:
        boundary: The boundary group whose nodes may touch the cylinder.
        point: A point of the axis (where the translation is 0).
        axis: The axis direction (3 components, any length > 0).
        radius: :math:`R > 0`.
        dhat: Barrier width :math:`\hat d > 0` (``None``: :func:`~hyperfem.contact.defaults.default_dhat`).
        stiffness: Barrier stiffness :math:`\kappa > 0` (``None``: the mean tangent diagonal at the contact nodes).
        motion: A translation of the cylinder, scaled by ``profile(t)`` (``None``: it stays), or a path ``t -> s(t)``
            (e.g. :class:`~hyperfem.loading.Waypoints`: pressed in, then dragged; ``profile`` is then unused).
        profile: :math:`f(t)` of the translation (default: the load factor).
        safety: The collision filter's :math:`s \in (0, 1)`.
        name: Prefix of the output columns (``contact_force``, ...).
        friction: Coulomb coefficient :math:`\mu \ge 0` (0: frictionless), smoothed and lagged per step.
        friction_epsilon: The slip length below which a node sticks elastically (``None``: :math:`0.1\,\hat d`).
        rotation: A :class:`~hyperfem.loading.RigidRotation` of the cylinder, composed with the translation
            (:mod:`~hyperfem.contact.obstacles`; ``None``: it does not turn).

    Raises:
        ParameterError: A bad entry (one line), or ``ipctk`` is not installed.
    """

    boundary: str
    point: Sequence[float]
    axis: Sequence[float]
    radius: float
    dhat: float | None = None
    stiffness: float | None = None
    motion: Motion = None
    profile: Callable[[float], float] = linear_profile
    safety: float = CCD_SAFETY
    name: str = "contact"
    friction: float = 0.0
    friction_epsilon: float | None = None
    rotation: RigidRotation | None = None

    def __post_init__(self) -> None:
        check_name(self.boundary, "boundary", "CylinderContact")
        where = f"CylinderContact on {self.boundary!r}"
        try:
            cylinder = Cylinder(self.point, self.axis, self.radius, self.motion, rotation=self.rotation)
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
        return Cylinder(self.point, self.axis, self.radius, self.motion, self.profile, self.rotation)

    def bind(self, problem: SolidProblem) -> CylinderBarrier:
        """The barrier of this contact on ``problem`` (collective).

        Raises:
            UnknownGroupError: ``boundary`` is not a boundary group of the mesh (the message lists them).
            ParameterError: The mesh is not 3D, or a node starts on or inside the cylinder.
        """
        return CylinderBarrier(self, problem)


class CylinderBarrier(SphereBarrier):
    r"""The barrier term :math:`\kappa B(u)` of a :class:`CylinderContact` on a problem (module docstring).

    The sphere's barrier with offsets, normals and Hessian in the plane normal to the axis.

    Attributes:
        dhat: :math:`\hat d`.
        stiffness: :math:`\kappa`.
        nodes: The owned contact nodes.
        step_filter: The collision filter.
        time: The time (load factor) the cylinder is at.
    """

    behind = "on or inside the cylinder"
    shape = "cylinder"

    def __init__(self, contact: CylinderContact, problem: SolidProblem):
        if problem.domain.gdim != 3:
            raise ParameterError(
                f"CylinderContact on {contact.boundary!r}: a cylinder needs a 3D mesh, got {problem.domain.gdim}D"
            )
        self.projector = contact.obstacle.projector
        super().__init__(contact, problem)  # type: ignore[arg-type, unused-ignore]  # the sphere's fields: boundary, radius, ...

    def _place(self, time: float) -> None:
        """Move (and turn) the cylinder to the obstacle time ``time``: its axis point and projector."""
        super()._place(time)
        self.projector = self.obstacle.projector_at(self.time)  # type: ignore[attr-defined]
        if hasattr(self, "step_filter"):
            self.step_filter.projector = self.projector
