r"""Mass density and the inertia (mass-weighted) integrals.

The consistent mass matrix is :math:`M_{ab} = \int_\Omega \rho\,N_a N_b\,dX`,
integrated exactly (quadrature degree :math:`2p` for degree-:math:`p`
elements). On quadrilaterals and hexahedra a degree counts per direction:
:math:`2p` is the :math:`(p+1)^d`-point Gauss rule, exact on
parallelepipeds; on a distorted (trilinear) hexahedron :math:`\det J` adds
degree 2 per direction, so the entries are the usual fully integrated ones
rather than exact, while the total mass (:math:`\int\rho\det J`) stays exact.
The lumped variant uses the vertex quadrature rule, which for linear (P1)
simplices gives the row-sum diagonal mass, and for Q1 on parallelepipeds
too (:math:`\rho|K|/2^d` to each vertex); it is refused for higher degrees,
where vertex lumping would leave nodes without mass.

Density may differ per region (physical-group name → :math:`\rho_r`).

:func:`lumped_mass` assembles the diagonal of the lumped mass as a vector
(what explicit time stepping divides by), :func:`total_mass` the mass
:math:`\sum_r \rho_r|\Omega_r|` that every mass matrix carries.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import ufl
from mpi4py import MPI
from dolfinx import fem, la

from hyperfem.errors import ParameterError
from hyperfem.mesh.domain import Domain
from hyperfem.validation import check_positive

__all__ = ["MassDensity", "lumped_mass", "total_mass"]


@dataclass(frozen=True)
class MassDensity:
    """Mass density per unit reference volume.

    Attributes:
        value: One density for the whole body, or region name → density.
        lumped: Use the lumped (diagonal) mass; P1 only.
    """

    value: float | Mapping[str, float]
    lumped: bool = False
    _regions: tuple = field(init=False, repr=False, compare=False, default=())

    def __post_init__(self) -> None:
        if isinstance(self.value, Mapping):
            if not self.value:
                raise ParameterError("MassDensity: region mapping is empty")
            for name, rho in self.value.items():
                check_positive(f"density of region {name!r}", rho, "MassDensity")
            object.__setattr__(self, "_regions", tuple(self.value.items()))
        else:
            check_positive("rho", self.value, "MassDensity")
            object.__setattr__(self, "_regions", ((None, float(self.value)),))

    def metadata(self, degree: int) -> dict:
        """Quadrature metadata of the mass integrals for displacement degree ``degree``."""
        if self.lumped:
            if degree != 1:
                raise ParameterError(f"MassDensity: lumped mass needs degree-1 elements, got degree {degree}")
            return {"quadrature_rule": "vertex", "quadrature_degree": 1}
        return {"quadrature_degree": 2 * degree}

    def integral(self, integrand: ufl.core.expr.Expr, domain: Domain, degree: int) -> ufl.Form:
        r""":math:`\sum_r \int_{\Omega_r} \rho_r\,(\text{integrand})\,dX` with the mass quadrature."""
        md = self.metadata(degree)
        mesh = domain.mesh
        # Densities enter as Constants: one compiled form serves every density.
        return sum(fem.Constant(mesh, rho) * integrand * domain.dx(name, metadata=md) for name, rho in self._regions)


def lumped_mass(density: MassDensity, domain: Domain, space: fem.FunctionSpace) -> fem.Function:
    r"""The diagonal of the lumped mass, :math:`m_a = \int_\Omega \rho\,N_a\,dX` per dof (row-sum lumping).

    Assembled with the vertex rule of :meth:`MassDensity.metadata` (for P1
    the row sums of the consistent mass: :math:`\rho|K|/(d+1)` to each vertex
    of a simplex, :math:`\rho|K|/2^d` of a parallelepiped), the same for
    every component of a vector space.

    Args:
        density: The density (``lumped`` or not: the diagonal is the same).
        domain: The mesh.
        space: A degree-1 Lagrange space (scalar or vector).

    Returns:
        A function on ``space`` whose entries (ghosts included) are the masses.

    Raises:
        ParameterError: For a space of degree other than 1.
    """
    degree = space.ufl_element().embedded_superdegree
    lumped = MassDensity(density.value, lumped=True)
    lumped.metadata(degree)  # refuses degree > 1
    v = ufl.TestFunction(space)
    ones = v if not space.value_shape else sum(v[i] for i in range(space.value_shape[0]))
    vec = fem.assemble_vector(fem.form(lumped.integral(ones, domain, degree)))
    vec.scatter_reverse(la.InsertMode.add)
    vec.scatter_forward()
    mass = fem.Function(space, name="lumped_mass")
    mass.x.array[:] = vec.array
    return mass


def total_mass(density: MassDensity, domain: Domain) -> float:
    r""":math:`\sum_r \rho_r |\Omega_r|`, reduced over the mesh communicator."""
    one = fem.Constant(domain.mesh, 1.0)
    form = fem.form(MassDensity(density.value).integral(one, domain, 1))
    return float(domain.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM))
