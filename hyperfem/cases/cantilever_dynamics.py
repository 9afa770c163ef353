r"""The eight dynamic cantilever experiments of seed 003, §5.7.

The 10 × 4 × 4 m beam (:func:`~hyperfem.mesh.beam_mesh`, clamped at
:math:`x = -5`, free end at :math:`x = +5`), compressible Neo-Hookean with
:math:`E = 10\cdot 10^5` Pa, :math:`\nu = 0.3`, :math:`\rho = 1000` kg/m³ and
viscous damping :math:`c = 0.0004\ \mathrm{s^{-1}}`:

========== =====================================================================
case       loading (time :math:`t` in s)
========== =====================================================================
bend       dead traction :math:`(0, -5, 0)` kPa on ``free_end`` from :math:`t = 0`
twist      follower traction :math:`5\,(0, z, -y)` kPa/m (current :math:`y, z`)
i-bend     bend traction ramped linearly from 0 to 5× during the first second
i-twist    twist traction ramped linearly from 0 to 5× during the first second
bc-bend    ``free_end`` rotated rigidly by :math:`\pi/2` about :math:`y` (axis
           through the face centre) during the first second
bc-twist   ``free_end`` rotated one full turn about :math:`x` during the first second
squeeze    both end caps moved along :math:`x` so the length goes 10 → 5 m
stretch    both end caps moved along :math:`x` so the length goes 10 → 20 m
========== =====================================================================

Choices the seed leaves open (documented here): the I-ramps start from zero
(seed: "linear increase ... to five times"), loads are held after the first
second; the twist traction is per unit *reference* area; in squeeze/stretch the
end caps move symmetrically and are held in :math:`y, z` (the clamp of the
``clamped`` face moves with it); in bc-* the ``clamped`` face stays clamped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hyperfem.cases.cantilever import TEST_POINT, CantileverSpec, bend_load, twist_load
from hyperfem.errors import ParameterError
from hyperfem.loading import Ramp, Steady, rotating_surface
from hyperfem.materials.neo_hookean import neo_hookean
from hyperfem.mesh.beam import LENGTH
from hyperfem.mesh.domain import Domain
from hyperfem.problem import Clamp, HyperelasticProblem, PrescribedDisplacement
from hyperfem.problem.boundary_conditions import BoundaryCondition
from hyperfem.problem.loads import Load

__all__ = ["CASES", "TEST_POINT", "CantileverDynamics", "cantilever_problem"]

CASES = ("bend", "twist", "i-bend", "i-twist", "bc-bend", "bc-twist", "squeeze", "stretch")


@dataclass(frozen=True)
class CantileverDynamics(CantileverSpec):
    """Data of the experiments (SI units): the material of
    :class:`~hyperfem.cases.CantileverSpec` plus the time data.

    Attributes:
        t_end: Simulated time (s).
        ramp_time: Duration of the ramps and prescribed motions (s).
        factor: Final multiple of the I-ramps.
    """

    t_end: float = 3.0
    ramp_time: float = 1.0
    factor: float = 5.0


def cantilever_problem(
    case: str, domain: Domain, spec: CantileverDynamics | None = None, degree: int = 1
) -> tuple[HyperelasticProblem, list[float]]:
    """Build the hyperelastic problem of one case; its time (``set_time``) is the physical time.

    Args:
        case: One of :data:`CASES`.
        domain: The beam (:func:`~hyperfem.mesh.beam_mesh`).
        spec: Material and loading data.
        degree: Displacement degree.

    Returns:
        The problem and its must-hit times (end of the ramp).
    """
    if case not in CASES:
        raise ParameterError(f"cantilever_problem: unknown case {case!r} (choose from {', '.join(CASES)})")
    spec = CantileverDynamics() if spec is None else spec
    params = spec.lame
    T = spec.ramp_time
    steady = Steady()
    ramp = Ramp(T, final=spec.factor)
    bcs: list[BoundaryCondition] = [Clamp("clamped")]
    loads: list[Load] = []
    must_hit: list[float] = []

    if case in ("bend", "i-bend"):
        loads.append(bend_load(profile=steady if case == "bend" else ramp))
    elif case in ("twist", "i-twist"):
        loads.append(twist_load(profile=steady if case == "twist" else ramp))
    elif case == "bc-bend":
        bcs.append(rotating_surface("free_end", (0.0, 1.0, 0.0), Ramp(T, final=math.pi / 2), (LENGTH / 2, 0.0, 0.0)))
    elif case == "bc-twist":
        bcs.append(rotating_surface("free_end", (1.0, 0.0, 0.0), Ramp(T, final=2 * math.pi), (LENGTH / 2, 0.0, 0.0)))
    else:
        # Each cap moves by a quarter (squeeze) or a half (stretch) of the length.
        shift = LENGTH / 4 if case == "squeeze" else -LENGTH / 2
        ramp1 = Ramp(T)
        bcs = [
            PrescribedDisplacement("clamped", (shift, 0.0, 0.0), profile=ramp1),
            PrescribedDisplacement("free_end", (-shift, 0.0, 0.0), profile=ramp1),
        ]
    if case != "bend" and case != "twist":
        must_hit.append(T)
    problem = HyperelasticProblem(domain, lambda F: neo_hookean(F, params), bcs=bcs, loads=loads, degree=degree)
    return problem, must_hit
