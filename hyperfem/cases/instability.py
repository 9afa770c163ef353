r"""Two set-ups past a limit point, for arc-length continuation (issue 22), shared by the demo and the tests.

**Inflated thick-walled sphere.** An incompressible neo-Hookean sphere,
:math:`\psi = \frac{\mu}{2}(\bar I_1 - 3)`, inner radius :math:`A`, outer
:math:`B`, under an internal pressure :math:`p` (a follower load). The
deformation is radial, :math:`r^3 = R^3 + a^3 - A^3`, and integrating the
radial equilibrium gives the pressure against the inner stretch
:math:`\lambda_a = a/A` (Ogden, *Non-linear elastic deformations*, §5.2;
:math:`\lambda_b = b/B`, :math:`b^3 = a^3 + B^3 - A^3`):

.. math::
    p(\lambda_a) = \mu\left[2\left(\frac{1}{\lambda_b} - \frac{1}{\lambda_a}\right)
    + \frac{1}{2}\left(\frac{1}{\lambda_b^4} - \frac{1}{\lambda_a^4}\right)\right].

It rises to a maximum (:math:`p/\mu = 0.81642` at :math:`\lambda_a = 1.828`
for :math:`A = 1, B = 2`) and falls beyond: under pressure control the
balloon "pops". One eighth is modelled (rollers on the symmetry planes),
with the three-field formulation (P2 displacement) and a bulk modulus
:math:`K = 10^3\mu`; the load factor is :math:`p/\mu`.

**Shallow clamped arch.** A neo-Hookean arch of span :math:`L = 10`,
thickness 0.2 and rise :math:`H`, clamped at both ends, held in its plane
(:math:`u_z = 0` on both faces), under its own weight (a dead body force
:math:`\lambda\,b`): it snaps through to the inverted shape, with a load
maximum, a descending branch and a minimum on the path. No closed form;
the limit loads are checked for their independence from the step size.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from dolfinx import mesh as dmesh
from mpi4py import MPI

from hyperfem.io.probes import PointProbe
from hyperfem.kinematics import isochoric_invariants
from hyperfem.materials.neo_hookean import neo_hookean
from hyperfem.materials.parameters import LameParameters
from hyperfem.mesh.domain import Domain
from hyperfem.mesh.shell import spherical_shell_mesh
from hyperfem.problem import HyperelasticProblem, MixedHyperelasticProblem, SplitEnergy
from hyperfem.problem.boundary_conditions import BoundaryCondition, Clamp, PrescribedDisplacement
from hyperfem.problem.loads import BodyForce, FollowerPressure

__all__ = [
    "SPHERE_PRESSURE_MAXIMUM",
    "InflatedSphere",
    "ShallowArch",
    "inflated_sphere",
    "shallow_arch",
    "sphere_pressure",
    "sphere_pressure_maximum",
]


def sphere_pressure(stretch: np.ndarray | float, inner: float = 1.0, outer: float = 2.0, mu: float = 1.0) -> np.ndarray:
    r"""The closed-form pressure :math:`p(\lambda_a)` of the inflated sphere (module docstring)."""
    la = np.asarray(stretch, dtype=float)
    lb = np.cbrt((la * inner) ** 3 + outer**3 - inner**3) / outer
    return mu * (2.0 * (1.0 / lb - 1.0 / la) + 0.5 * (lb**-4 - la**-4))


def sphere_pressure_maximum(inner: float = 1.0, outer: float = 2.0, mu: float = 1.0) -> tuple[float, float]:
    """The maximum of :func:`sphere_pressure` and the inner stretch where it lies (golden-section search)."""
    a, b = 1.0, 10.0
    g = (np.sqrt(5.0) - 1.0) / 2.0
    for _ in range(200):
        c, d = b - g * (b - a), a + g * (b - a)
        if sphere_pressure(c, inner, outer, mu) > sphere_pressure(d, inner, outer, mu):
            b = d
        else:
            a = c
    x = 0.5 * (a + b)
    return float(sphere_pressure(x, inner, outer, mu)), float(x)


SPHERE_PRESSURE_MAXIMUM = sphere_pressure_maximum()
"""(p_max/μ, λ_a at it) for A = 1, B = 2: (0.816424, 1.828)."""


@dataclass
class InflatedSphere:
    """The inflated-sphere problem and its probe.

    Attributes:
        problem: The three-field problem; load factor = :math:`p/\\mu`.
        inner_stretch: :math:`\\lambda_a` at the current state (the inner
            radius on the x axis over :math:`A`; collective).
        inner: :math:`A`.
        outer: :math:`B`.
        mu: Shear modulus.
    """

    problem: MixedHyperelasticProblem
    inner_stretch: Callable[[], float]
    inner: float
    outer: float
    mu: float


def inflated_sphere(
    h: float = 0.5, inner: float = 1.0, outer: float = 2.0, mu: float = 1.0, bulk_ratio: float = 1e3,
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> InflatedSphere:
    """One eighth of the sphere, three-field P2/P1, rollers on the planes, pressure ``λ μ`` on ``inner``.

    Args:
        h: Element size (curved second-order tetrahedra).
        inner: :math:`A`.
        outer: :math:`B`.
        mu: Shear modulus.
        bulk_ratio: :math:`K/\\mu`.
        comm: Communicator.
    """
    domain = spherical_shell_mesh(inner, outer, h=h, order=2, comm=comm)
    material = SplitEnergy(lambda F: 0.5 * mu * (isochoric_invariants(F)[0] - 3.0), bulk_ratio * mu)
    rollers = [PrescribedDisplacement(name, [0.0], components=[i]) for i, name in enumerate(("x0", "y0", "z0"))]
    problem = MixedHyperelasticProblem(domain, material, bcs=rollers, loads=[FollowerPressure("inner", mu)], degree=2)
    probe = PointProbe(domain.mesh, [[inner, 0.0, 0.0]])

    def inner_stretch() -> float:
        return 1.0 + float(probe(problem.u.sub(0).collapse())[0, 0]) / inner

    return InflatedSphere(problem, inner_stretch, inner, outer, mu)


@dataclass
class ShallowArch:
    """The shallow arch and its probe.

    Attributes:
        problem: The displacement problem (P2); load factor = body-force scale.
        crown_deflection: Vertical displacement of the crown's top (collective).
        rise: :math:`H`.
    """

    problem: HyperelasticProblem
    crown_deflection: Callable[[], float]
    rise: float


ARCH_SPAN, ARCH_THICKNESS = 10.0, 0.2
ARCH_MATERIAL = LameParameters.from_youngs(1000.0, 0.3)
ARCH_WEIGHT = 0.05
"""Body force per unit volume at load factor 1."""


def shallow_arch(rise: float = 0.5, cells: int = 16, comm: MPI.Comm = MPI.COMM_WORLD) -> ShallowArch:
    """The arch of the module docstring: ``cells`` x 1 x 1 boxes of P2 tetrahedra mapped onto a parabola.

    Args:
        rise: :math:`H`.
        cells: Boxes along the span.
        comm: Communicator.
    """
    L, t = ARCH_SPAN, ARCH_THICKNESS
    mesh = dmesh.create_box(comm, [[0.0, 0.0, 0.0], [L, t, t]], [cells, 1, 1], dmesh.CellType.tetrahedron)
    x = mesh.geometry.x
    x[:, 1] += rise * (1.0 - (2.0 * x[:, 0] / L - 1.0) ** 2)
    domain = Domain.from_locators(
        mesh,
        {
            "x0": lambda x: np.isclose(x[0], 0.0),
            "x1": lambda x: np.isclose(x[0], L),
            "z0": lambda x: np.isclose(x[2], 0.0),
            "z1": lambda x: np.isclose(x[2], t),
        },
        source=f"shallow_arch(rise={rise}, cells={cells})",
    )
    bcs: list[BoundaryCondition] = [
        Clamp("x0"),
        Clamp("x1"),
        PrescribedDisplacement("z0", [0.0], components=[2]),
        PrescribedDisplacement("z1", [0.0], components=[2]),
    ]
    problem = HyperelasticProblem(
        domain,
        lambda F: neo_hookean(F, ARCH_MATERIAL),
        bcs=bcs,
        loads=[BodyForce([0.0, -ARCH_WEIGHT, 0.0])],
        degree=2,
    )
    probe = PointProbe(domain.mesh, [[L / 2, rise + t, t / 2]])

    def crown_deflection() -> float:
        return float(probe(problem.u)[0, 1])

    return ShallowArch(problem, crown_deflection, rise)
