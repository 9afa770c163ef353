r"""Prescribed rigid motions of a named surface.

A translation path through waypoints (:class:`Waypoints`: a tool that
indents, then drags), and a rigid rotation of a surface about an axis, by an
angle that follows a time profile (:mod:`hyperfem.loading.profiles`):

.. math::
    u(X, t) = R\bigl(\theta(t)\,\hat a\bigr)(X - c) + c - X,

with :math:`R` the rotation by angle :math:`\theta(t)` about the unit axis
:math:`\hat a` through the point :math:`c` (Rodrigues' formula,
:math:`R = I + \sin\theta\,[\hat a]_\times + (1-\cos\theta)[\hat a]_\times^2`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hyperfem.errors import ParameterError
from hyperfem.validation import is_finite_number

if TYPE_CHECKING:
    from hyperfem.problem.boundary_conditions import PrescribedDisplacement

__all__ = ["RigidRotation", "Waypoints", "rotating_surface", "rotation_matrix"]


def rotation_matrix(axis: Sequence[float], angle: float) -> np.ndarray:
    r"""Rotation by ``angle`` (radians, right-handed) about ``axis`` (Rodrigues)."""
    try:
        a = np.asarray(axis, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"rotation_matrix: axis must be a non-zero finite 3-vector, got {axis!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
        raise ParameterError(f"rotation_matrix: axis must be a non-zero finite 3-vector, got {axis!r}")
    n = np.linalg.norm(a)
    if not math.isfinite(float(angle)):
        raise ParameterError(f"rotation_matrix: angle must be a finite number, got {angle!r}")
    a = a / n
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


@dataclass(frozen=True)
class RigidRotation:
    r"""Displacement of a rigid rotation, :math:`u = R(\theta(t))(X - c) + c - X`.

    An instance is a callable ``value(x, t)`` as accepted by
    :class:`~hyperfem.problem.PrescribedDisplacement`: it is re-evaluated at
    every time. ``x`` has shape ``(3, npoints)`` (reference coordinates).

    Attributes:
        axis: Rotation axis (normalised internally).
        angle: :math:`\theta(t)` in radians.
        center: A point on the axis.
    """

    axis: Sequence[float]
    angle: Callable[[float], float]
    center: Sequence[float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        rotation_matrix(self.axis, 0.0)  # validates the axis
        if len(self.center) != 3 or not all(is_finite_number(c) for c in self.center):
            raise ParameterError(f"RigidRotation: center must be 3 finite coordinates, got {self.center!r}")
        if not callable(self.angle):
            raise ParameterError(f"RigidRotation: angle must be a callable angle(t), got {self.angle!r}")

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        R = self.matrix(t)
        c = np.asarray(self.center, dtype=float).reshape(3, 1)
        X = x[:3]
        return R @ (X - c) + c - X

    def matrix(self, t: float) -> np.ndarray:
        r"""The rotation :math:`R(\theta(t)\,\hat a)` at time ``t``, shape ``(3, 3)``.

        Raises:
            ParameterError: :math:`\theta(t)` is not a finite number (one line).
        """
        try:
            angle = float(self.angle(t))
        except (TypeError, ValueError):
            raise ParameterError(f"RigidRotation: angle({t:g}) must be a finite number") from None
        if not math.isfinite(angle):
            raise ParameterError(f"RigidRotation: angle({t:g}) must be a finite number, got {angle!r}")
        return rotation_matrix(self.axis, angle)

    def rotate(self, points: np.ndarray, t: float) -> np.ndarray:
        r""":math:`R(\theta(t))(x - c) + c` of points ``x`` of shape ``(m, 3)`` (or one point, ``(3,)``)."""
        c = np.asarray(self.center, dtype=float)
        return (np.asarray(points, dtype=float) - c) @ self.matrix(t).T + c


def rotating_surface(
    boundary: str,
    axis: Sequence[float],
    angle: Callable[[float], float],
    center: Sequence[float] = (0.0, 0.0, 0.0),
) -> PrescribedDisplacement:
    """Prescribe a rigid rotation of the named surface about ``axis`` through ``center``.

    Args:
        boundary: Physical-group name of the surface.
        axis: Rotation axis.
        angle: Angle :math:`\\theta(t)` (radians) as a function of time.
        center: A point on the axis.

    Returns:
        A :class:`~hyperfem.problem.PrescribedDisplacement` on all components.
    """
    # Imported here: hyperfem.problem imports hyperfem.loading (its default profile).
    from hyperfem.problem.boundary_conditions import PrescribedDisplacement

    return PrescribedDisplacement(boundary, RigidRotation(tuple(axis), angle, tuple(center)))


@dataclass(frozen=True)
class Waypoints:
    r"""A translation path, piecewise linear through ``(times[k], points[k])`` and held at its ends.

    A moving obstacle's ``motion`` (e.g. :class:`~hyperfem.contact.ToolContact`): a probe pressed
    down by :math:`\delta` until :math:`t = 1/2`, then dragged along :math:`x` by :math:`L`, is
    ``Waypoints(times=(0, 0.5, 1), points=((0, 0, 0), (0, 0, -delta), (L, 0, -delta)))``.

    Attributes:
        times: Strictly increasing times (load factors or s), at least 2.
        points: The translation at those times, one vector (2 or 3 components) per time.
    """

    times: Sequence[float]
    points: Sequence[Sequence[float]]

    def __post_init__(self) -> None:
        t = list(self.times)
        try:
            x = np.asarray(self.points, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"Waypoints: points must be equal-length vectors, got {self.points!r}") from None
        if len(t) < 2 or x.ndim != 2 or len(x) != len(t) or x.shape[1] not in (2, 3):
            raise ParameterError(
                f"Waypoints: need one 2- or 3-vector per time (at least 2), got {len(t)} times and points of shape "
                f"{x.shape}"
            )
        if not all(is_finite_number(v) for v in t) or not np.all(np.isfinite(x)):
            raise ParameterError("Waypoints: times and points must be finite numbers")
        if any(b <= a for a, b in itertools.pairwise(t)):
            raise ParameterError(f"Waypoints: times must increase strictly, got {t}")
        object.__setattr__(self, "times", tuple(float(v) for v in t))
        object.__setattr__(self, "points", tuple(tuple(float(v) for v in row) for row in x))

    def __call__(self, t: float) -> np.ndarray:
        x = np.asarray(self.points)
        return np.array([np.interp(float(t), self.times, x[:, k]) for k in range(x.shape[1])])

    @property
    def kinks(self) -> tuple[float, ...]:
        """Times where the path turns (every waypoint's time)."""
        return tuple(self.times)
