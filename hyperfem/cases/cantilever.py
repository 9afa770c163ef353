r"""Erleben's cantilever beam (seed 003, §5.7).

A 10 × 4 × 4 m beam, :math:`x \in [-5, 5]`, clamped at :math:`x = -5`, loaded on
the free end :math:`x = +5`; compressible Neo-Hookean with
:math:`E = 10\cdot 10^5` Pa, :math:`\nu = 0.3`, :math:`\rho = 1000` kg/m³.

* *bend*: dead traction :math:`t = (0, -5, 0)` kPa;
* *twist*: :math:`t = 5\,\text{kPa}\,(0, z, -y)` with :math:`y, z` the *current*
  coordinates of the surface point — a follower load. We take it per unit
  reference area (the seed integrates over the current surface; for this
  nearly rigid end section the difference is the area change of the end
  face, well below 1 % here).

The test point is :math:`(4.5, 1.5, 1.5)`.
"""

from __future__ import annotations

from dataclasses import dataclass

import ufl

from hyperfem.materials.parameters import LameParameters
from hyperfem.problem.loads import DeadTraction, FollowerTraction

__all__ = ["BEND_TRACTION", "TEST_POINT", "TWIST_MAGNITUDE", "CantileverSpec", "bend_load", "twist_load"]

TEST_POINT = (4.5, 1.5, 1.5)
BEND_TRACTION = (0.0, -5.0e3, 0.0)  # Pa
TWIST_MAGNITUDE = 5.0e3  # Pa per metre of lever arm


@dataclass(frozen=True)
class CantileverSpec:
    """Material data of the cantilever experiments (SI units).

    Attributes:
        E: Young's modulus (Pa).
        nu: Poisson's ratio.
        rho: Mass density (kg/m³).
        damping: Viscous damping coefficient c (1/s).
    """

    E: float = 10.0e5
    nu: float = 0.3
    rho: float = 1000.0
    damping: float = 0.0004

    @property
    def lame(self) -> LameParameters:
        """Lamé parameters from (E, ν)."""
        return LameParameters.from_youngs(self.E, self.nu)


def bend_load(scale: float = 1.0, profile=None) -> DeadTraction:
    """Dead traction ``scale * (0, -5, 0) kPa`` on ``free_end``."""
    t = tuple(scale * c for c in BEND_TRACTION)
    return DeadTraction("free_end", t) if profile is None else DeadTraction("free_end", t, profile)


def twist_load(scale: float = 1.0, profile=None) -> FollowerTraction:
    """Follower traction ``scale * 5 kPa * (0, z, -y)`` (current y, z) on ``free_end``."""

    def traction(x):
        return scale * TWIST_MAGNITUDE * ufl.as_vector((0.0, x[2], -x[1]))

    return FollowerTraction("free_end", traction) if profile is None else FollowerTraction(
        "free_end", traction, profile
    )
