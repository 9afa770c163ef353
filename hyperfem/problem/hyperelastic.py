r"""The quasi-static hyperelastic boundary-value problem.

Given strain-energy densities :math:`\psi_r(F)` per region, dead loads and
follower loads, :class:`HyperelasticProblem` builds (once)

.. math::
    \Pi(u) = \sum_r \int_{\Omega_r} \psi_r(F)\,dX - W_\text{dead}(u),\qquad
    R(u; v) = \frac{\partial \Pi}{\partial u}[v] + R_\text{follower}(u; v),\qquad
    K(u; v, \delta u) = \frac{\partial R}{\partial u}[\delta u],

with both derivatives taken by ``ufl.derivative``. Loads are
:class:`dolfinx.fem.Constant` magnitudes set by :meth:`set_load_factor`; the
forms never need recompiling.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import ufl
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.kinematics import deformation_gradient
from hyperfem.mesh.domain import Domain
from hyperfem.problem.boundary_conditions import BoundaryCondition, _CompiledDirichlet
from hyperfem.problem.base import EnergyProblem
from hyperfem.problem.loads import Load

__all__ = ["EnergyDensity", "HyperelasticProblem", "default_quadrature_degree"]

EnergyDensity = Callable[[ufl.core.expr.Expr], ufl.core.expr.Expr]


def default_quadrature_degree(degree: int) -> int:
    """Quadrature degree used for displacement degree ``degree``.

    P1: one point (F is constant per cell); P2 and higher: ``2 * degree``.
    """
    return 1 if degree == 1 else 2 * degree


class HyperelasticProblem(EnergyProblem):
    """Energy, residual and tangent of a hyperelastic body.

    Args:
        domain: Mesh with named groups.
        material: Strain-energy density ``psi(F)``, or a mapping region name →
            ``psi(F)`` for several materials (every cell must belong to one).
        bcs: Dirichlet conditions (:class:`~hyperfem.problem.Clamp`,
            :class:`~hyperfem.problem.PrescribedDisplacement`).
        loads: External loads (dead and follower).
        degree: Lagrange degree of the displacement.
        quadrature_degree: Quadrature degree; default from
            :func:`default_quadrature_degree`.

    Attributes:
        u: The displacement :class:`dolfinx.fem.Function`.
        energy_internal, energy_external: UFL forms of the stored energy and
            the work of the dead loads (``Pi = internal - external``).
        follower_residual: Sum of the non-conservative residual terms, or ``None``.
        residual, jacobian: UFL forms passed to the solver.
        conservative: ``True`` when every load derives from :math:`\\Pi`, so the
            line search can use the energy as its merit function.
    """

    def __init__(
        self,
        domain: Domain,
        material: EnergyDensity | Mapping[str, EnergyDensity],
        *,
        bcs: Sequence[BoundaryCondition] = (),
        loads: Sequence[Load] = (),
        degree: int = 1,
        quadrature_degree: int | None = None,
    ):
        if degree < 1:
            raise ParameterError(f"HyperelasticProblem: degree must be >= 1, got {degree}")
        self.domain = domain
        mesh = domain.mesh
        gdim = domain.gdim
        self.degree = degree
        self.quadrature_degree = quadrature_degree or default_quadrature_degree(degree)
        md = {"quadrature_degree": self.quadrature_degree}
        self.V = fem.functionspace(mesh, ("Lagrange", degree, (gdim,)))
        self.u = fem.Function(self.V, name="displacement")
        v = ufl.TestFunction(self.V)
        du = ufl.TrialFunction(self.V)
        self.F = deformation_gradient(self.u)

        # Stored energy, per region.
        if callable(material):
            self.energy_internal = material(self.F) * domain.dx(metadata=md)
        else:
            if not material:
                raise ParameterError("HyperelasticProblem: material mapping is empty")
            self.energy_internal = sum(
                psi(self.F) * domain.dx(name, metadata=md) for name, psi in material.items()
            )
        self._dirichlet = [_CompiledDirichlet(bc, self.V, domain) for bc in bcs]

        # Loads: one Constant magnitude each, scaled by its profile.
        self._derive_forms(self.u, v, v, du, loads)
