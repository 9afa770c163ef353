r"""Rigid obstacles of contact: a half-space (a plane) and a ball (a sphere), with a prescribed translation.

The obstacle :math:`\{x : (x - p(t))\cdot n < 0\}` with the unit outward
normal :math:`n` and the point

.. math::
    p(t) = p_0 + f(t)\,m,

:math:`m` the translation (``motion``) and :math:`f` its profile in load factor
or time (:mod:`hyperfem.loading.profiles`, as for the values of a
:class:`~hyperfem.problem.PrescribedDisplacement`). The signed distance of a
point :math:`x` from the plane is :math:`d(x) = (x - p(t))\cdot n`: positive
on the body's side. A :class:`Ball` of radius :math:`R` centred at
:math:`c(t) = c_0 + f(t)\,m` gives :math:`d(x) = |x - c(t)| - R`, positive
outside; an infinite :class:`Cylinder` of radius :math:`R` about the axis
through :math:`c(t)` along the unit :math:`a` gives
:math:`d(x) = |P(x - c(t))| - R`, :math:`P = I - a a^T`. Triangulated tools
are :class:`~hyperfem.contact.ToolContact`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hyperfem.errors import ParameterError
from hyperfem.loading.profiles import linear_profile
from hyperfem.validation import check_callable, check_finite_vector, check_positive

__all__ = ["Ball", "Cylinder", "HalfSpace", "check_ball", "check_plane"]


def check_plane(
    point: Sequence[float], normal: Sequence[float], motion: Sequence[float] | None, where: str
) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...] | None]:
    """The point, normal and motion of a plane as float tuples of one length (2 or 3); a one-line error otherwise.

    Raises:
        ParameterError: A non-finite entry, a length other than 2 or 3, lengths
            that differ, or a normal of zero length.
    """
    p = check_finite_vector(point, where, "point")
    n = check_finite_vector(normal, where, "normal")
    m = None if motion is None else check_finite_vector(motion, where, "motion")
    for what, v in (("point", p), ("normal", n), ("motion", m)):
        if v is not None and len(v) not in (2, 3):
            raise ParameterError(f"{where}: {what} must have 2 or 3 components, got {len(v)}")
        if v is not None and len(v) != len(p):
            raise ParameterError(f"{where}: {what} has {len(v)} components, point has {len(p)}")
    if not float(np.linalg.norm(n)) > 0.0:
        raise ParameterError(f"{where}: normal must be a non-zero vector, got {n}")
    return p, n, m


@dataclass(frozen=True)
class HalfSpace:
    r"""A rigid half-space with outward normal ``normal`` through ``point``, translated by ``profile(t)·motion``.

    Attributes:
        point: A point :math:`p_0` of the plane at :math:`t` with ``profile(t) = 0``.
        normal: The outward normal (normalised by :attr:`unit_normal`), pointing to the body's side.
        motion: The translation :math:`m` (``None``: the plane does not move).
        profile: :math:`f(t)` of the translation (default: the load factor).
    """

    point: Sequence[float]
    normal: Sequence[float]
    motion: Sequence[float] | None = None
    profile: Callable[[float], float] = linear_profile

    def __post_init__(self) -> None:
        p, n, m = check_plane(self.point, self.normal, self.motion, "HalfSpace")
        check_callable(self.profile, "HalfSpace", "profile")
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

    def origin(self, t: float) -> np.ndarray:
        """The point :math:`p(t) = p_0 + f(t)\\,m` of the plane at time (load factor) ``t``."""
        p = np.asarray(self.point, dtype=float)
        if self.motion is None:
            return p
        return p + float(self.profile(t)) * np.asarray(self.motion, dtype=float)

    def signed_distance(self, x: np.ndarray, t: float) -> np.ndarray:
        r""":math:`(x - p(t))\cdot n` of points ``x`` (shape ``(m, dim)``): positive on the body's side."""
        return (np.asarray(x, dtype=float) - self.origin(t)) @ self.unit_normal


def check_ball(
    center: Sequence[float], radius: float, motion: Sequence[float] | None, where: str
) -> tuple[tuple[float, ...], float, tuple[float, ...] | None]:
    """The centre, radius and motion of a sphere (float tuples of one length, 2 or 3); a one-line error otherwise.

    Raises:
        ParameterError: A non-finite entry, a length other than 2 or 3, lengths
            that differ, or a radius that is not a finite number > 0.
    """
    c = check_finite_vector(center, where, "center")
    m = None if motion is None else check_finite_vector(motion, where, "motion")
    for what, v in (("center", c), ("motion", m)):
        if v is not None and len(v) not in (2, 3):
            raise ParameterError(f"{where}: {what} must have 2 or 3 components, got {len(v)}")
        if v is not None and len(v) != len(c):
            raise ParameterError(f"{where}: {what} has {len(v)} components, center has {len(c)}")
    check_positive("radius", radius, where)
    return c, float(radius), m


@dataclass(frozen=True)
class Ball:
    r"""A rigid ball of radius ``radius`` centred at ``center``, translated by ``profile(t)·motion``.

    Attributes:
        center: The centre :math:`c_0` at :math:`t` with ``profile(t) = 0``.
        radius: :math:`R > 0`.
        motion: The translation :math:`m` (``None``: the ball does not move).
        profile: :math:`f(t)` of the translation (default: the load factor).
    """

    center: Sequence[float]
    radius: float
    motion: Sequence[float] | None = None
    profile: Callable[[float], float] = linear_profile

    def __post_init__(self) -> None:
        c, r, m = check_ball(self.center, self.radius, self.motion, "Ball")
        check_callable(self.profile, "Ball", "profile")
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "motion", m)

    @property
    def dim(self) -> int:
        """The number of components (2 or 3)."""
        return len(self.center)

    def origin(self, t: float) -> np.ndarray:
        """The centre :math:`c(t) = c_0 + f(t)\\,m` at time (load factor) ``t``."""
        c = np.asarray(self.center, dtype=float)
        if self.motion is None:
            return c
        return c + float(self.profile(t)) * np.asarray(self.motion, dtype=float)

    def signed_distance(self, x: np.ndarray, t: float) -> np.ndarray:
        r""":math:`|x - c(t)| - R` of points ``x`` (shape ``(m, dim)``): positive outside."""
        return np.linalg.norm(np.asarray(x, dtype=float) - self.origin(t), axis=1) - float(self.radius)


@dataclass(frozen=True)
class Cylinder:
    r"""A rigid infinite cylinder (a roller, a rod) of radius ``radius`` about the axis through ``point``.

    Attributes:
        point: A point of the axis at :math:`t` with ``profile(t) = 0``.
        axis: The axis direction (normalised by :attr:`unit_axis`), 3 components.
        radius: :math:`R > 0`.
        motion: The translation :math:`m` (``None``: it stays).
        profile: :math:`f(t)` of the translation (default: the load factor).
    """

    point: Sequence[float]
    axis: Sequence[float]
    radius: float
    motion: Sequence[float] | None = None
    profile: Callable[[float], float] = linear_profile

    def __post_init__(self) -> None:
        c, r, m = check_ball(self.point, self.radius, self.motion, "Cylinder")
        a = check_finite_vector(self.axis, "Cylinder", "axis")
        if len(c) != 3 or len(a) != 3:
            raise ParameterError(f"Cylinder: point and axis must have 3 components, got {len(c)} and {len(a)}")
        if not float(np.linalg.norm(a)) > 0.0:
            raise ParameterError(f"Cylinder: axis must be a non-zero vector, got {a}")
        check_callable(self.profile, "Cylinder", "profile")
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
        """:math:`P = I - a a^T`, the projection onto the plane normal to the axis."""
        a = self.unit_axis
        return np.eye(3) - np.outer(a, a)

    def origin(self, t: float) -> np.ndarray:
        """The axis point :math:`c(t) = c_0 + f(t)\\,m` at time (load factor) ``t``."""
        c = np.asarray(self.point, dtype=float)
        if self.motion is None:
            return c
        return c + float(self.profile(t)) * np.asarray(self.motion, dtype=float)

    def signed_distance(self, x: np.ndarray, t: float) -> np.ndarray:
        r""":math:`|P(x - c(t))| - R` of points ``x`` (shape ``(m, 3)``): positive outside."""
        q = (np.asarray(x, dtype=float) - self.origin(t)) @ self.projector
        return np.linalg.norm(q, axis=1) - float(self.radius)
