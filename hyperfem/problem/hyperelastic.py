r"""The quasi-static hyperelastic boundary-value problem.

Given strain-energy densities :math:`\psi_r(F)` per region, dead loads and
follower loads, :class:`HyperelasticProblem` builds (once)

.. math::
    \Pi(u) = \sum_r \int_{\Omega_r} \psi_r(F)\,dX - W_\text{dead}(u),\qquad
    R(u; v) = \frac{\partial \Pi}{\partial u}[v] + R_\text{follower}(u; v),\qquad
    K(u; v, \delta u) = \frac{\partial R}{\partial u}[\delta u],

with both derivatives taken by ``ufl.derivative``. Loads are
:class:`dolfinx.fem.Constant` magnitudes set by :meth:`set_time`; the
forms never need recompiling.

Energies are callables ``psi(F)``. An energy may also declare the extras of
:class:`~hyperfem.problem.protocol.EnergyProtocol` (a plain callable gets the
neutral ones from :func:`~hyperfem.problem.energy.as_energy`):

* ``invertible`` — finite and restoring for :math:`J \le 0`
  (:mod:`hyperfem.materials.invertibility`); the problem is
  ``invertible`` when every region's energy is;
* ``bind(F, quadrature_degree)`` — called before ``psi(F)`` with the
  problem's :math:`F` and volume rule (energies with quadrature fields);
  ``quadrature_rule_degree`` — the rule such fields need (``None``: any);
* ``state_hooks`` — callables collected into :attr:`state_hooks`, which
  :class:`~hyperfem.solver.NewtonSolver` runs at every new state before
  assembly (e.g. the polar-rotation refresh of fixed-corotated/ARAP);
* ``updaters`` — objects with ``update(t)`` added to the problem's updaters
  (e.g. the step rotation of corotational linear elasticity);
* ``tangent_correction(F)`` — a pseudo-energy whose second variation is
  added to the tangent only (the :math:`\partial R/\partial F` term).
"""

from __future__ import annotations

import numbers
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TypeVar

import ufl
from dolfinx import fem
from dolfinx.mesh import CellType

from hyperfem.errors import ParameterError
from hyperfem.kinematics import deformation_gradient
from hyperfem.mesh.domain import Domain
from hyperfem.problem.boundary_conditions import BoundaryCondition, _CompiledDirichlet
from hyperfem.problem.base import EnergyProblem
from hyperfem.problem.energy import as_energy, check_region_coverage, scalar_energy
from hyperfem.problem.loads import Load
from hyperfem.problem.protocol import EnergyProtocol, Updater
from hyperfem.problem.quadrature import check_volume_quadrature, volume_quadrature_degree

__all__ = ["EnergyDensity", "HyperelasticProblem", "default_quadrature_degree"]

EnergyDensity = Callable[[ufl.core.expr.Expr], ufl.core.expr.Expr]


def default_quadrature_degree(degree: int, cell_type: CellType | None = None) -> int:
    """Quadrature degree used for displacement degree ``degree`` on cells of ``cell_type``.

    Simplices (and ``cell_type=None``): P1 one point (F is constant per
    cell), P2 and higher ``2 * degree``. Quadrilaterals and hexahedra:
    ``2 * degree`` for every degree, Q1 included (full Gauss integration; the
    one-point rule has hourglass modes). See
    :func:`~hyperfem.problem.quadrature.volume_quadrature_degree`.
    """
    return volume_quadrature_degree(degree, cell_type)


T = TypeVar("T")


def as_sequence(items: Iterable[T], what: str, where: str) -> list[T]:
    """``items`` as a list; a single condition or load (or a non-sequence) is an error."""
    # Boundary: items is user input of any type; only iterability is asked of it.
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
            :func:`default_quadrature_degree` for the mesh's cell type
            (on hexahedra and quadrilaterals a degree counts per direction).
        updaters: Objects with ``update(t)`` that :meth:`set_time` calls
            (e.g. :class:`~hyperfem.loading.Activation`); the energies'
            own ``updaters`` are added (each once).
        invertible: Whether the energies tolerate :math:`J \\le 0` (the solver
            may then drop its inversion guard); ``None``: inferred, ``True``
            when every region's energy is marked invertible.

    Attributes:
        u: The displacement :class:`dolfinx.fem.Function`.
        energy_internal, energy_external: UFL forms of the stored energy and
            the work of the dead loads (``Pi = internal - external``).
        follower_residual: Sum of the non-conservative residual terms, or ``None``.
        residual, jacobian: UFL forms passed to the solver.
        conservative: ``True`` when every load derives from :math:`\\Pi`, so the
            line search can use the energy as its merit function.
        invertible: See the argument.
        state_hooks: The energies' state hooks (module docstring), for the solver.
        tangent_correction: The energies' tangent corrections as a form, or ``None``.
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
        invertible: bool | None = None,
    ):
        where = "HyperelasticProblem"
        _check_arguments(domain, degree, quadrature_degree, invertible, where)
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
        self.quadrature_degree = quadrature_degree or default_quadrature_degree(degree, mesh.topology.cell_type)
        check_volume_quadrature(degree, self.quadrature_degree, mesh.topology.cell_type, where)
        self._check_domain(domain, [(gdim, degree)], self.quadrature_degree)  # flat cells, size guard
        self.V = fem.functionspace(mesh, ("Lagrange", degree, (gdim,)))
        self.u = fem.Function(self.V, name="displacement")
        v = ufl.TestFunction(self.V)
        du = ufl.TrialFunction(self.V)
        self.F = deformation_gradient(self.u)
        regions = _material_regions(domain, material, where)
        energies, own_updaters, correction = self._add_energies(regions, updaters, invertible, where)
        self._dirichlet = [_CompiledDirichlet(bc, self.V, domain) for bc in bcs]
        # Loads: one Constant magnitude each, scaled by its profile.
        self._derive_forms(self.u, v, v, du, loads, updaters=own_updaters, tangent_correction=correction)
        self._check_rule_of_point_fields(energies, where)

    def _add_energies(
        self,
        regions: dict[str | None, EnergyDensity],
        updaters: Iterable[Updater],
        invertible: bool | None,
        where: str,
    ) -> tuple[list[tuple[EnergyDensity, EnergyProtocol]], list[Updater], ufl.Form | None]:
        r"""The stored energy :math:`\sum_r \int_{\Omega_r} \psi_r(F)\,dX` and what the energies declare.

        Binds each distinct energy to :attr:`F` on the volume rule and sets
        :attr:`energy_internal`, :attr:`invertible` and :attr:`state_hooks`.

        Returns:
            Each distinct energy with its :class:`~hyperfem.problem.protocol.EnergyProtocol` view;
            the problem's updaters (``updaters``, then the energies' own, each once);
            the energies' tangent corrections as one form, or ``None``.
        """
        md = {"quadrature_degree": self.quadrature_degree}
        domain = self.domain
        distinct = list({id(psi): psi for psi in regions.values()}.values())
        energies = {id(psi): as_energy(psi) for psi in distinct}
        for psi in regions.values():
            energies[id(psi)].bind(self.F, self.quadrature_degree)
        self.energy_internal = sum(
            scalar_energy(psi, self.F, f"{where}, " + ("whole domain" if name is None else f"region {name!r}"))
            * domain.dx(name, metadata=md)
            for name, psi in regions.items()
        )
        materials = [energies[id(psi)] for psi in distinct]
        self.invertible = all(bool(e.invertible) for e in materials) if invertible is None else invertible
        self.state_hooks = tuple(hook for energy in materials for hook in energy.state_hooks)
        own_updaters = as_sequence(updaters, "updaters", where)
        for energy in materials:
            for updater in energy.updaters:
                if not any(updater is other for other in own_updaters):
                    own_updaters.append(updater)
        corrections = [(name, energies[id(psi)].tangent_correction(self.F)) for name, psi in regions.items()]
        corrections = [(name, c) for name, c in corrections if c is not None]
        correction = (
            sum(c * domain.dx(name, metadata=md) for name, c in corrections) if corrections else None
        )
        return [(psi, energies[id(psi)]) for psi in distinct], own_updaters, correction

    def _check_rule_of_point_fields(self, energies: list[tuple[EnergyDensity, EnergyProtocol]], where: str) -> None:
        """Energies holding fields on quadrature points need the volume rule unchanged by the loads."""
        on_points = [psi for psi, energy in energies if energy.quadrature_rule_degree is not None]
        if on_points:
            raised = {
                itg.metadata().get("quadrature_degree")
                for itg in self.energy_internal.integrals()
                if itg.integral_type() == "cell"
            } - {self.quadrature_degree}
            if raised:
                raise ParameterError(
                    f"{where}: the loads raise the volume rule to degree {max(raised)}, but "
                    f"{type(on_points[0]).__name__} holds fields on the points of degree {self.quadrature_degree}; "
                    f"pass quadrature_degree={max(raised)}"
                )


def _check_arguments(domain: object, degree: object, quadrature_degree: object, invertible: object, where: str) -> None:
    """The domain, the degrees and ``invertible`` of a :class:`HyperelasticProblem`."""
    if not isinstance(domain, Domain):
        raise ParameterError(
            f"{where}: domain must be a hyperfem Domain (hf.read_mesh, hf.beam_mesh, Domain.from_locators), "
            f"got {type(domain).__name__}"
        )
    if not (isinstance(degree, numbers.Integral) and not isinstance(degree, bool) and int(degree) >= 1):
        raise ParameterError(f"{where}: degree must be an integer >= 1, got {degree!r}")
    if quadrature_degree is not None and not (
        isinstance(quadrature_degree, numbers.Integral)
        and not isinstance(quadrature_degree, bool)
        and int(quadrature_degree) >= 1
    ):
        raise ParameterError(f"{where}: quadrature_degree must be an integer >= 1 or None, got {quadrature_degree!r}")
    if invertible is not None and not isinstance(invertible, bool):
        raise ParameterError(f"{where}: invertible must be True, False or None, got {invertible!r}")


def _material_regions(
    domain: Domain, material: EnergyDensity | Mapping[str, EnergyDensity], where: str
) -> dict[str | None, EnergyDensity]:
    """Region name (``None``: the whole domain) → energy; a mapping's regions must cover the mesh (collective)."""
    if callable(material):
        return {None: material}
    if not material:
        raise ParameterError(f"{where}: material mapping is empty")
    check_region_coverage(domain, list(material), where)
    return {name: psi for name, psi in material.items()}
