r"""Rigid obstacles of contact: a half-space, a ball and a cylinder, with a prescribed translation and rotation.

The obstacle :math:`\{x : (x - p(t))\cdot n < 0\}` with the unit outward
normal :math:`n` and the point

.. math::
    p(t) = p_0 + s(t), \qquad s(t) = f(t)\,m,

:math:`m` the translation (``motion``) and :math:`f` its profile in load factor
or time (:mod:`hyperfem.loading.profiles`, as for the values of a
:class:`~hyperfem.problem.PrescribedDisplacement`), or a path ``motion``
:math:`s(t)` itself (e.g. :class:`~hyperfem.loading.Waypoints`: pressed in,
then dragged; :data:`Motion`). The signed distance of a
point :math:`x` from the plane is :math:`d(x) = (x - p(t))\cdot n`: positive
on the body's side. A :class:`Ball` of radius :math:`R` centred at
:math:`c(t) = c_0 + s(t)` gives :math:`d(x) = |x - c(t)| - R`, positive
outside; an infinite :class:`Cylinder` of radius :math:`R` about the axis
through :math:`c(t)` along the unit :math:`a` gives
:math:`d(x) = |P(x - c(t))| - R`, :math:`P = I - a a^T`. Triangulated tools
are :class:`~hyperfem.contact.ToolContact`.

**Rotation.** A plane, a ball and a cylinder (and a tool,
:class:`~hyperfem.contact.mesh_barrier.RigidSurface`) may also turn: a
:class:`~hyperfem.loading.RigidRotation` (unit axis :math:`\hat a_r`, pivot
:math:`c_r`, angle :math:`\theta(t)`) is composed with the translation, the
rotation first, about the pivot in the obstacle's reference placement, which
then travels with the translation:

.. math::
    x(t) = R\bigl(\theta(t)\,\hat a_r\bigr)(X - c_r) + c_r + s(t),

so the cylinder's axis point is :math:`c(t) = R(c_0 - c_r) + c_r + s(t)`
and its axis :math:`a(t) = R a_0`, a plane's point :math:`p(t)` likewise and its
normal :math:`n(t) = R n_0`. A ball turned about its own centre does
not change its shape; its surface moves all the same, which matters with
friction (the slip is taken relative to the obstacle's surface,
:mod:`~hyperfem.contact.nodal`). :meth:`Ball.transfer` maps points rigidly
from the placement at one time to the placement at another (the predictor
carries nodes with it).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hyperfem.errors import ParameterError
from hyperfem.loading.motion import RigidRotation
from hyperfem.loading.profiles import linear_profile
from hyperfem.validation import check_callable, check_finite_vector, check_positive

__all__ = [
    "Ball",
    "Cylinder",
    "HalfSpace",
    "RigidPlacement",
    "Motion",
    "check_ball",
    "check_motion",
    "check_plane",
    "check_rotation",
    "obstacle_time",
]


Motion = Sequence[float] | Callable[[float], Sequence[float]] | None
"""An obstacle's translation: a vector scaled by ``profile(t)``, a path ``t -> s(t)`` (e.g.
:class:`~hyperfem.loading.Waypoints`; ``profile`` is then unused), or ``None`` (it stays)."""


def obstacle_time(problem: object, t: float) -> float:
    r"""The time a prescribed obstacle is placed at when its barrier is moved to the load time ``t``.

    The barrier keeps the end state :math:`u_{n+1}` of a step out, so a moving
    obstacle is where it is at the Dirichlet time :math:`t_{n+1}`
    (:meth:`~hyperfem.dynamics.IncrementalProblem.dirichlet_time`); the solver
    moves its energies to the load time, :math:`t_{n+1-\alpha_f}` under
    generalized-:math:`\alpha`. Placed there instead, the obstacle would lag
    :math:`\alpha_f\Delta t` behind the state it keeps out: the end state of a
    step would be intersection-free against an obstacle that has moved on. Under
    generalized-:math:`\alpha` its force enters the balance interpolated between
    the step's ends, :math:`(1-\alpha_f)f_c(u_{n+1}, t_{n+1}) + \alpha_f f_c(u_n, t_n)`
    (:mod:`~hyperfem.contact.interpolation`). The same time for every other
    problem and scheme.
    """
    mapping = getattr(problem, "dirichlet_time", None)
    return float(t) if mapping is None else float(mapping(t))


def check_rotation(rotation: object, dim: int, where: str) -> RigidRotation | None:
    r"""``rotation`` if it is ``None`` or a :class:`~hyperfem.loading.RigidRotation` of a 3D obstacle with a finite
    :math:`\theta(0)`; a one-line error otherwise.

    Raises:
        ParameterError: Not a ``RigidRotation``, a 2D obstacle, or :math:`\theta(0)` not a finite number.
    """
    if rotation is None:
        return None
    if not isinstance(rotation, RigidRotation):
        raise ParameterError(
            f"{where}: rotation must be a hyperfem.loading.RigidRotation(axis, angle, center), got {rotation!r}"
        )
    if dim != 3:
        raise ParameterError(f"{where}: a rotation needs a 3D obstacle, got {dim} components")
    try:
        rotation.matrix(0.0)
    except ParameterError as exc:
        raise ParameterError(f"{where}: rotation {str(exc).removeprefix('RigidRotation: ')}") from None
    return rotation


class RigidPlacement:
    r"""The rigid motion of an obstacle, :math:`x(t) = R(t)(X - c_r) + c_r + s(t)` (module docstring).

    Mixed into the obstacles; reads their ``motion``, ``profile`` and ``rotation``.
    """

    motion: Motion
    profile: Callable[[float], float]
    rotation: RigidRotation | None = None

    def translation(self, t: float) -> np.ndarray | float:
        r""":math:`f(t)\,m`, or a path's :math:`s(t)` (0 where the obstacle does not translate)."""
        if self.motion is None:
            return 0.0
        if callable(self.motion):  # a path (e.g. Waypoints): the translation itself
            return np.asarray(self.motion(t), dtype=float)
        return float(self.profile(t)) * np.asarray(self.motion, dtype=float)

    def turn(self, t: float) -> np.ndarray | None:
        r""":math:`R(\theta(t))`, or ``None`` without a rotation."""
        return None if self.rotation is None else self.rotation.matrix(t)

    def place(self, points: np.ndarray | Sequence[float], t: float) -> np.ndarray:
        """Points of the reference placement (``(m, dim)`` or ``(dim,)``) where they are at time ``t``."""
        x = np.asarray(points, dtype=float)
        if self.rotation is not None:
            x = self.rotation.rotate(x, t)
        return x + self.translation(t)

    def transfer(self, points: np.ndarray, t_from: float, t: float) -> np.ndarray:
        r"""Points moved rigidly with the obstacle from its placement at ``t_from`` to its placement at ``t``.

        :math:`x' = R(t)R(t_0)^T(x - c_r - s_0) + c_r + s`, :math:`s` the translations.
        """
        x = np.asarray(points, dtype=float)
        if self.rotation is None:
            return x + (self.translation(t) - self.translation(t_from))
        c = np.asarray(self.rotation.center, dtype=float)
        Q = self.rotation.matrix(t) @ self.rotation.matrix(t_from).T
        return (x - self.translation(t_from) - c) @ Q.T + c + self.translation(t)

    def increments(self, points: np.ndarray, t_from: float, t: float) -> np.ndarray:
        """:meth:`transfer` minus the points, ``(m, dim)`` (the translation itself, exactly, without a rotation)."""
        x = np.asarray(points, dtype=float)
        if self.rotation is None:
            return np.broadcast_to(self.translation(t) - self.translation(t_from), x.shape).copy()
        return self.transfer(x, t_from, t) - x


def check_motion(motion: Motion, dim: int, where: str) -> tuple[float, ...] | Callable[[float], Sequence[float]] | None:
    """A motion (:data:`Motion`) of ``dim`` components: a float tuple, the path itself, or ``None``; one line else.

    Raises:
        ParameterError: A non-finite entry or another number of components (a path: at ``t = 0``).
    """
    if motion is None:
        return None
    if callable(motion):
        try:
            start = np.asarray(motion(0.0), dtype=float)
        except Exception as exc:  # a user's callable: whatever it raises, one line
            why = " ".join(f"{type(exc).__name__}: {exc}".split())
            raise ParameterError(f"{where}: a motion path must give {dim} numbers at t = 0 ({why})") from None
        if start.shape != (dim,) or not np.all(np.isfinite(start)):
            raise ParameterError(f"{where}: a motion path must give {dim} finite components, got "
                                 f"{start.ravel().tolist()} (shape {start.shape}) at t = 0")
        return motion
    m = check_finite_vector(motion, where, "motion")
    if len(m) != dim:
        raise ParameterError(f"{where}: motion must have {dim} components, got {len(m)}")
    return m


def check_plane(
    point: Sequence[float], normal: Sequence[float], motion: Motion, where: str
) -> tuple[tuple[float, ...], tuple[float, ...], Motion]:
    """The point, normal and motion of a plane as float tuples of one length (2 or 3); a one-line error otherwise.

    Raises:
        ParameterError: A non-finite entry, a length other than 2 or 3, lengths
            that differ, or a normal of zero length.
    """
    p = check_finite_vector(point, where, "point")
    n = check_finite_vector(normal, where, "normal")
    m = None if motion is None or callable(motion) else check_finite_vector(motion, where, "motion")
    for what, v in (("point", p), ("normal", n), ("motion", m)):
        if v is not None and len(v) not in (2, 3):
            raise ParameterError(f"{where}: {what} must have 2 or 3 components, got {len(v)}")
        if v is not None and len(v) != len(p):
            raise ParameterError(f"{where}: {what} has {len(v)} components, point has {len(p)}")
    if not float(np.linalg.norm(n)) > 0.0:
        raise ParameterError(f"{where}: normal must be a non-zero vector, got {n}")
    return p, n, check_motion(motion, len(p), where)


@dataclass(frozen=True)
class HalfSpace(RigidPlacement):
    r"""A rigid half-space with outward normal ``normal`` through ``point``, turned by ``rotation`` and translated by
    ``profile(t)·motion``.

    Attributes:
        point: A point :math:`p_0` of the plane where the translation is 0 and with no rotation.
        normal: The outward normal (normalised by :attr:`unit_normal`), pointing to the body's side.
        motion: The translation :math:`m` (``None``: the plane does not move), or a path (:data:`Motion`).
        profile: :math:`f(t)` of the translation (default: the load factor).
        rotation: A :class:`~hyperfem.loading.RigidRotation` composed with the translation: it turns the normal,
            :math:`n(t) = R(t)\,n_0`, and the point about the pivot (module docstring; ``None``: it does not turn).
    """

    point: Sequence[float]
    normal: Sequence[float]
    motion: Motion = None
    profile: Callable[[float], float] = linear_profile
    rotation: RigidRotation | None = None

    def __post_init__(self) -> None:
        p, n, m = check_plane(self.point, self.normal, self.motion, "HalfSpace")
        check_callable(self.profile, "HalfSpace", "profile")
        check_rotation(self.rotation, len(p), "HalfSpace")
        object.__setattr__(self, "point", p)
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "motion", m)

    @property
    def dim(self) -> int:
        """The number of components (2 or 3)."""
        return len(self.point)

    @property
    def unit_normal(self) -> np.ndarray:
        """:math:`n / |n|`."""
        n = np.asarray(self.normal, dtype=float)
        return n / np.linalg.norm(n)

    def normal_at(self, t: float) -> np.ndarray:
        """The unit normal :math:`n(t) = R(t)\\,n_0` at time (load factor) ``t``."""
        R = self.turn(t)
        return self.unit_normal if R is None else R @ self.unit_normal

    def origin(self, t: float) -> np.ndarray:
        """The point :math:`p(t) = R(t)(p_0 - c_r) + c_r + s(t)` of the plane at time (load factor) ``t``."""
        return self.place(self.point, t)

    def signed_distance(self, x: np.ndarray, t: float) -> np.ndarray:
        r""":math:`(x - p(t))\cdot n(t)` of points ``x`` (shape ``(m, dim)``): positive on the body's side."""
        return (np.asarray(x, dtype=float) - self.origin(t)) @ self.normal_at(t)


def check_ball(
    center: Sequence[float], radius: float, motion: Motion, where: str
) -> tuple[tuple[float, ...], float, Motion]:
    """The centre, radius and motion of a sphere (float tuples of one length, 2 or 3); a one-line error otherwise.

    Raises:
        ParameterError: A non-finite entry, a length other than 2 or 3, lengths
            that differ, or a radius that is not a finite number > 0.
    """
    c = check_finite_vector(center, where, "center")
    m = None if motion is None or callable(motion) else check_finite_vector(motion, where, "motion")
    for what, v in (("center", c), ("motion", m)):
        if v is not None and len(v) not in (2, 3):
            raise ParameterError(f"{where}: {what} must have 2 or 3 components, got {len(v)}")
        if v is not None and len(v) != len(c):
            raise ParameterError(f"{where}: {what} has {len(v)} components, center has {len(c)}")
    check_positive("radius", radius, where)
    return c, float(radius), check_motion(motion, len(c), where)


@dataclass(frozen=True)
class Ball(RigidPlacement):
    r"""A rigid ball of radius ``radius`` centred at ``center``, turned by ``rotation`` and translated by
    ``profile(t)·motion``.

    Attributes:
        center: The centre :math:`c_0` where the translation is 0 and with no rotation.
        radius: :math:`R > 0`.
        motion: The translation :math:`m` (``None``: the ball does not move), or a path (:data:`Motion`).
        profile: :math:`f(t)` of the translation (default: the load factor).
        rotation: A :class:`~hyperfem.loading.RigidRotation` composed with the translation (module docstring;
            ``None``: it does not turn).
    """

    center: Sequence[float]
    radius: float
    motion: Motion = None
    profile: Callable[[float], float] = linear_profile
    rotation: RigidRotation | None = None

    def __post_init__(self) -> None:
        c, r, m = check_ball(self.center, self.radius, self.motion, "Ball")
        check_callable(self.profile, "Ball", "profile")
        check_rotation(self.rotation, len(c), "Ball")
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "motion", m)

    @property
    def dim(self) -> int:
        """The number of components (2 or 3)."""
        return len(self.center)

    def origin(self, t: float) -> np.ndarray:
        """The centre :math:`c(t) = R(t)(c_0 - c_r) + c_r + s(t)` at time (load factor) ``t``."""
        return self.place(self.center, t)

    def signed_distance(self, x: np.ndarray, t: float) -> np.ndarray:
        r""":math:`|x - c(t)| - R` of points ``x`` (shape ``(m, dim)``): positive outside."""
        return np.linalg.norm(np.asarray(x, dtype=float) - self.origin(t), axis=1) - float(self.radius)


@dataclass(frozen=True)
class Cylinder(RigidPlacement):
    r"""A rigid infinite cylinder (a roller, a rod) of radius ``radius`` about the axis through ``point``.

    Attributes:
        point: A point of the axis where the translation is 0.
        axis: The axis direction (normalised by :attr:`unit_axis`), 3 components.
        radius: :math:`R > 0`.
        motion: The translation :math:`m` (``None``: it stays), or a path (:data:`Motion`).
        profile: :math:`f(t)` of the translation (default: the load factor).
        rotation: A :class:`~hyperfem.loading.RigidRotation` composed with the translation: it turns the axis
            (module docstring; ``None``: it does not turn).
    """

    point: Sequence[float]
    axis: Sequence[float]
    radius: float
    motion: Motion = None
    profile: Callable[[float], float] = linear_profile
    rotation: RigidRotation | None = None

    def __post_init__(self) -> None:
        c, r, m = check_ball(self.point, self.radius, self.motion, "Cylinder")
        a = check_finite_vector(self.axis, "Cylinder", "axis")
        if len(c) != 3 or len(a) != 3:
            raise ParameterError(f"Cylinder: point and axis must have 3 components, got {len(c)} and {len(a)}")
        if not float(np.linalg.norm(a)) > 0.0:
            raise ParameterError(f"Cylinder: axis must be a non-zero vector, got {a}")
        check_callable(self.profile, "Cylinder", "profile")
        check_rotation(self.rotation, 3, "Cylinder")
        object.__setattr__(self, "point", c)
        object.__setattr__(self, "axis", a)
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "motion", m)

    @property
    def dim(self) -> int:
        """The number of components (3)."""
        return len(self.point)

    @property
    def unit_axis(self) -> np.ndarray:
        """:math:`a / |a|`."""
        a = np.asarray(self.axis, dtype=float)
        return a / np.linalg.norm(a)

    @property
    def projector(self) -> np.ndarray:
        """:math:`P = I - a a^T`, the projection onto the plane normal to the axis (in the reference placement)."""
        a = self.unit_axis
        return np.eye(3) - np.outer(a, a)

    def axis_at(self, t: float) -> np.ndarray:
        """The unit axis :math:`a(t) = R(t)\\,a_0` at time (load factor) ``t``."""
        R = self.turn(t)
        return self.unit_axis if R is None else R @ self.unit_axis

    def projector_at(self, t: float) -> np.ndarray:
        """:math:`P(t) = I - a(t) a(t)^T`."""
        a = self.axis_at(t)
        return np.eye(3) - np.outer(a, a)

    def origin(self, t: float) -> np.ndarray:
        """The axis point :math:`c(t) = R(t)(c_0 - c_r) + c_r + s(t)` at time (load factor) ``t``."""
        return self.place(self.point, t)

    def signed_distance(self, x: np.ndarray, t: float) -> np.ndarray:
        r""":math:`|P(t)(x - c(t))| - R` of points ``x`` (shape ``(m, 3)``): positive outside."""
        q = (np.asarray(x, dtype=float) - self.origin(t)) @ self.projector_at(t)
        return np.linalg.norm(q, axis=1) - float(self.radius)
