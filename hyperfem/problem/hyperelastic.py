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

import numbers
from collections.abc import Callable, Iterable, Mapping, Sequence

import ufl
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.kinematics import deformation_gradient
from hyperfem.mesh.domain import Domain
from hyperfem.problem.boundary_conditions import BoundaryCondition, _CompiledDirichlet
from hyperfem.problem.base import EnergyProblem
from hyperfem.problem.loads import Load
from hyperfem.problem.protocol import Updater
from hyperfem.problem.validation import check_region_coverage, scalar_energy

__all__ = ["EnergyDensity", "HyperelasticProblem", "default_quadrature_degree"]

EnergyDensity = Callable[[ufl.core.expr.Expr], ufl.core.expr.Expr]


def default_quadrature_degree(degree: int) -> int:
    """Quadrature degree used for displacement degree ``degree``.

    P1: one point (F is constant per cell); P2 and higher: ``2 * degree``.
    """
    return 1 if degree == 1 else 2 * degree


def as_sequence(items, what: str, where: str) -> list:
    """``items`` as a list; a single condition or load (or a non-sequence) is an error."""
    if isinstance(items, (str, bytes, Mapping)) or not hasattr(items, "__iter__"):
        raise ParameterError(f"{where}: {what} must be a list or tuple, got {type(items).__name__}")
    return list(items)


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
        updaters: Objects with ``update(t)`` that :meth:`set_time` calls
            (e.g. :class:`~hyperfem.activation.Activation`).

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
        updaters: Iterable[Updater] = (),
    ):
        where = "HyperelasticProblem"
        if not isinstance(domain, Domain):
            raise ParameterError(
                f"{where}: domain must be a hyperfem Domain (hf.read_mesh, hf.beam_mesh, Domain.from_locators), "
                f"got {type(domain).__name__}"
            )
        if not (isinstance(degree, numbers.Integral) and not isinstance(degree, bool) and degree >= 1):
            raise ParameterError(f"{where}: degree must be an integer >= 1, got {degree!r}")
        if quadrature_degree is not None and not (
            isinstance(quadrature_degree, numbers.Integral)
            and not isinstance(quadrature_degree, bool)
            and quadrature_degree >= 1
        ):
            raise ParameterError(
                f"{where}: quadrature_degree must be an integer >= 1 or None, got {quadrature_degree!r}"
            )
        bcs = as_sequence(bcs, "bcs", where)
        loads = as_sequence(loads, "loads", where)
        if not (callable(material) or isinstance(material, Mapping)):
            raise ParameterError(
                f"{where}: material must be an energy psi(F) or a mapping region name -> psi(F), "
                f"got {type(material).__name__}"
            )
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
            psi = scalar_energy(material, self.F, f"{where}, whole domain")
            self.energy_internal = psi * domain.dx(metadata=md)
        else:
            if not material:
                raise ParameterError(f"{where}: material mapping is empty")
            check_region_coverage(domain, list(material), where)
            self.energy_internal = sum(
                scalar_energy(psi, self.F, f"{where}, region {name!r}") * domain.dx(name, metadata=md)
                for name, psi in material.items()
            )
        self._dirichlet = [_CompiledDirichlet(bc, self.V, domain) for bc in bcs]

        # Loads: one Constant magnitude each, scaled by its profile.
        self._derive_forms(self.u, v, v, du, loads, updaters=updaters)
