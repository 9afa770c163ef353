r"""External loads by physical-group name.

Conservative (dead) loads enter the total potential energy,

.. math::
    \Pi(u) = \int_\Omega \psi(F)\,dX - \int_\Omega b\cdot u\,dX - \sum_k \int_{\Gamma_k} t_k\cdot u\,dA,

non-conservative (follower) loads add a residual term whose tangent UFL
derives with ``ufl.derivative``:

* :class:`FollowerTraction` — :math:`-\int_\Gamma t(x)\cdot v\,dA` with
  :math:`x = X + u` the current position; force per unit *reference* area.
* :class:`FollowerPressure` — :math:`+\int_\Gamma p\,J F^{-T}N\cdot v\,dA`
  (Nanson's formula); positive ``p`` pushes against the outward normal.

Every load is multiplied by ``profile(s)`` with ``s`` the load factor or time.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from hyperfem.problem.boundary_conditions import linear_profile

__all__ = ["BodyForce", "DeadTraction", "FollowerPressure", "FollowerTraction", "Load"]


@dataclass(frozen=True)
class DeadTraction:
    """Traction of fixed direction and magnitude per unit reference area.

    Attributes:
        boundary: Physical-group name.
        value: Constant vector, or a callable ``value(X) -> UFL vector`` of the
            reference coordinates.
        profile: Scaling with the load factor/time.
    """

    boundary: str
    value: Sequence[float] | Callable
    profile: Callable[[float], float] = linear_profile


@dataclass(frozen=True)
class FollowerTraction:
    """Traction that depends on the *current* position ``x = X + u``.

    Attributes:
        boundary: Physical-group name.
        value: Callable ``value(x) -> UFL vector`` of the current coordinates,
            or a constant vector. Force per unit reference area.
        profile: Scaling with the load factor/time.
    """

    boundary: str
    value: Sequence[float] | Callable
    profile: Callable[[float], float] = linear_profile


@dataclass(frozen=True)
class FollowerPressure:
    """Pressure acting normal to the deformed surface (Nanson's formula).

    Attributes:
        boundary: Physical-group name.
        value: Pressure (force per unit *current* area); positive compresses.
        profile: Scaling with the load factor/time.
    """

    boundary: str
    value: float
    profile: Callable[[float], float] = linear_profile


@dataclass(frozen=True)
class BodyForce:
    """Body force per unit reference volume.

    Attributes:
        value: Constant vector or callable ``value(X) -> UFL vector``.
        region: Physical-group name of the region, ``None`` for everywhere.
        profile: Scaling with the load factor/time.
    """

    value: Sequence[float] | Callable
    region: str | None = None
    profile: Callable[[float], float] = linear_profile


Load = DeadTraction | FollowerTraction | FollowerPressure | BodyForce
