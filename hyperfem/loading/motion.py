r"""Prescribed rigid motions of a named surface.

A rigid rotation of a surface about an axis, by an angle that follows a time
profile (:mod:`hyperfem.loading.profiles`):

.. math::
    u(X, t) = R\bigl(\theta(t)\,\hat a\bigr)(X - c) + c - X,

with :math:`R` the rotation by angle :math:`\theta(t)` about the unit axis
:math:`\hat a` through the point :math:`c` (Rodrigues' formula,
:math:`R = I + \sin\theta\,[\hat a]_\times + (1-\cos\theta)[\hat a]_\times^2`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hyperfem.errors import ParameterError
from hyperfem.validation import is_finite_number

if TYPE_CHECKING:
    from hyperfem.problem.boundary_conditions import PrescribedDisplacement

__all__ = ["RigidRotation", "rotating_surface", "rotation_matrix"]


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
        R = rotation_matrix(self.axis, float(self.angle(t)))
        c = np.asarray(self.center, dtype=float).reshape(3, 1)
        X = x[:3]
        return R @ (X - c) + c - X


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
