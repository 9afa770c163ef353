r"""Mixed displacement–pressure (u–p) formulation for nearly incompressible solids.

With the energy split :math:`\psi = \psi_\text{iso}(F) + \frac{K}{2} g(J)^2`
(:math:`g = \ln J` or :math:`J - 1`), the perturbed-Lagrangian functional

.. math::
    \Pi(u, p) = \sum_r \int_{\Omega_r} \Big[\psi_{\text{iso},r}(F) + p\, g_r(J)
        - \frac{p^2}{2K_r}\Big]\,dX - W_\text{dead}(u)

is made stationary over Taylor–Hood :math:`P_2/P_1` (by default) displacement
and pressure. Eliminating :math:`p = K g(J)` pointwise recovers the
displacement energy; discretely the pressure is continuous and of lower
degree, so large :math:`K` no longer locks the displacement. Residual and
tangent are ``ufl.derivative`` of :math:`\Pi` with respect to the mixed
unknown :math:`w = (u, p)`.

:class:`MixedHyperelasticProblem` satisfies the solver protocol of
:class:`~hyperfem.solver.NewtonSolver`: ``u`` is the *mixed* function, the
displacement is :attr:`~MixedHyperelasticProblem.displacement` (call
:meth:`~MixedHyperelasticProblem.update_fields`). Because :math:`\Pi` is a
saddle point in :math:`p`, it cannot be a line-search merit function, so the
problem reports ``conservative = False`` and the solver uses a residual-based
line search.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import basix.ufl
import numpy as np
import ufl
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.materials.parameters import check_positive
from hyperfem.materials.volumetric import volumetric_law
from hyperfem.mesh.domain import Domain
from hyperfem.problem.boundary_conditions import BoundaryCondition, _CompiledDirichlet
from hyperfem.problem.hyperelastic import HyperelasticProblem, default_quadrature_degree
from hyperfem.problem.base import EnergyProblem
from hyperfem.problem.loads import Load

__all__ = ["MixedHyperelasticProblem", "ReactionForce", "SplitEnergy", "solid_problem"]

Expr = ufl.core.expr.Expr


@dataclass(frozen=True)
class SplitEnergy:
    r"""An energy split into isochoric and volumetric parts, :math:`\psi_\text{iso}(F) + U(J)`.

    Attributes:
        isochoric: :math:`\psi_\text{iso}(F)` (a function of the deformation gradient).
        bulk_modulus: :math:`K > 0`.
        volumetric: Volumetric law name; the mixed formulation needs one of
            the form :math:`\frac{K}{2} g(J)^2` (``"log"``, ``"quadratic"``).
    """

    isochoric: Callable[[Expr], Expr]
    bulk_modulus: float
    volumetric: str = "log"

    def __post_init__(self) -> None:
        check_positive("bulk_modulus", self.bulk_modulus, "SplitEnergy")
        volumetric_law(self.volumetric)

    def energy(self, F: Expr) -> Expr:
        """The full energy :math:`\\psi(F)` (for the pure displacement formulation)."""
        return self.isochoric(F) + volumetric_law(self.volumetric).energy(ufl.det(F), self.bulk_modulus)

    def mixed_energy(self, F: Expr, p: Expr) -> Expr:
        r""":math:`\psi_\text{iso}(F) + p\,g(J) - p^2/(2K)`."""
        g = volumetric_law(self.volumetric).pressure_measure
        if g is None:
            raise ParameterError(
                f"SplitEnergy: volumetric law {self.volumetric!r} is not of the form K/2 g(J)^2; "
                "use 'log' or 'quadratic' with the mixed formulation"
            )
        return self.isochoric(F) + p * g(ufl.det(F)) - p**2 / (2.0 * self.bulk_modulus)


class MixedHyperelasticProblem(EnergyProblem):
    """Taylor–Hood u–p problem of a nearly incompressible body.

    Args:
        domain: Mesh with named groups.
        material: A :class:`SplitEnergy`, or a mapping region name →
            :class:`SplitEnergy` (every cell must belong to one region).
        bcs: Displacement Dirichlet conditions (by boundary name).
        loads: External loads (dead and follower), as for
            :class:`~hyperfem.problem.HyperelasticProblem`.
        degree: Displacement degree (default 2).
        pressure_degree: Pressure degree (default ``degree - 1``; Taylor–Hood).
        quadrature_degree: Default :func:`~hyperfem.problem.default_quadrature_degree` of ``degree``.
        updaters: Objects with ``update(s)`` called by :meth:`set_load_factor`
            (e.g. :class:`~hyperfem.activation.Activation`).

    Attributes:
        u: The mixed unknown :math:`w = (u, p)` (what the solver updates).
        displacement, pressure: Collapsed copies, refreshed by :meth:`update_fields`.
        F: Deformation gradient (UFL, from the displacement block).
        p: Pressure (UFL, from the pressure block).
    """

    saddle_point = True

    def __init__(
        self,
        domain: Domain,
        material: SplitEnergy | Mapping[str, SplitEnergy],
        *,
        bcs: Sequence[BoundaryCondition] = (),
        loads: Sequence[Load] = (),
        degree: int = 2,
        pressure_degree: int | None = None,
        quadrature_degree: int | None = None,
        updaters: Iterable = (),
    ):
        pressure_degree = degree - 1 if pressure_degree is None else pressure_degree
        if degree < 2 or not 1 <= pressure_degree < degree:
            raise ParameterError(
                f"MixedHyperelasticProblem: need degree >= 2 and 1 <= pressure_degree < degree, "
                f"got {degree}/{pressure_degree}"
            )
        self.domain = domain
        mesh = domain.mesh
        gdim = domain.gdim
        self.degree = degree
        self.pressure_degree = pressure_degree
        self.quadrature_degree = quadrature_degree or default_quadrature_degree(degree)
        md = {"quadrature_degree": self.quadrature_degree}
        cell = mesh.basix_cell()
        el_u = basix.ufl.element("Lagrange", cell, degree, shape=(gdim,))
        el_p = basix.ufl.element("Lagrange", cell, pressure_degree)
        self.W = fem.functionspace(mesh, basix.ufl.mixed_element([el_u, el_p]))
        self.u = fem.Function(self.W, name="state")
        self.V, self._u_dofs = self.W.sub(0).collapse()
        self.Q, self._p_dofs = self.W.sub(1).collapse()
        self.displacement = fem.Function(self.V, name="displacement")
        self.pressure = fem.Function(self.Q, name="pressure")
        u, p = ufl.split(self.u)
        v = ufl.TestFunction(self.W)
        v_u, _ = ufl.split(v)
        dw = ufl.TrialFunction(self.W)
        self.p = p
        self.F = ufl.Identity(gdim) + ufl.grad(u)

        if isinstance(material, SplitEnergy):
            self.energy_internal = material.mixed_energy(self.F, p) * domain.dx(metadata=md)
        else:
            if not material:
                raise ParameterError("MixedHyperelasticProblem: material mapping is empty")
            self.energy_internal = sum(
                m.mixed_energy(self.F, p) * domain.dx(name, metadata=md) for name, m in material.items()
            )
        self.material = material
        self._dirichlet = [_CompiledDirichlet(bc, self.W.sub(0), domain) for bc in bcs]

        # Pi is stationary, not minimal, in p: never use it as a line-search merit.
        self._derive_forms(u, v, v_u, dw, loads, conservative=False, updaters=updaters)

    def update_fields(self) -> tuple[fem.Function, fem.Function]:
        """Copy the displacement and pressure blocks into :attr:`displacement`, :attr:`pressure`."""
        self.displacement.x.array[:] = self.u.x.array[self._u_dofs]
        self.pressure.x.array[:] = self.u.x.array[self._p_dofs]
        return self.displacement, self.pressure


def solid_problem(
    domain: Domain,
    material: SplitEnergy | Mapping[str, SplitEnergy],
    *,
    formulation: str = "mixed",
    degree: int | None = None,
    **kwargs,
):
    """Build the problem of a split energy in the chosen formulation.

    Args:
        domain: Mesh with named groups.
        material: Split energy (or mapping region → split energy).
        formulation: ``"mixed"`` (Taylor–Hood u–p) or ``"displacement"``.
        degree: Displacement degree (default 2 for mixed, 1 for displacement).
        **kwargs: Passed on (``bcs``, ``loads``, ``quadrature_degree``, ``updaters``...);
            with ``updaters`` the displacement problem is wrapped in an
            :class:`~hyperfem.activation.ActivatedProblem`.
    """
    if formulation == "mixed":
        return MixedHyperelasticProblem(domain, material, degree=degree or 2, **kwargs)
    if formulation == "displacement":
        updaters = list(kwargs.pop("updaters", ()))
        psi = material.energy if isinstance(material, SplitEnergy) else {k: m.energy for k, m in material.items()}
        problem = HyperelasticProblem(domain, psi, degree=degree or 1, **kwargs)
        if updaters:
            from hyperfem.activation import ActivatedProblem

            return ActivatedProblem(problem, updaters)
        return problem
    raise ParameterError(f"unknown formulation {formulation!r} (use 'mixed' or 'displacement')")


class ReactionForce:
    r"""Total force :math:`\int_\Gamma P N\,dA` exerted on the body at a named (Dirichlet) boundary.

    Computed from the residual of the stored energy,
    :math:`R_i = \partial\Pi_\text{int}/\partial u\,[e_i \chi_\Gamma]`, with
    :math:`\chi_\Gamma` the finite-element function that is 1 at the dofs of
    the boundary and 0 elsewhere (exact for the discrete equilibrium). The
    form is compiled once.

    Args:
        problem: A :class:`~hyperfem.problem.HyperelasticProblem` or
            :class:`MixedHyperelasticProblem` (or an object wrapping one).
        boundary: Boundary name.
    """

    def __init__(self, problem, boundary: str):
        domain = problem.domain
        self.comm = domain.comm
        W = problem.u.function_space
        mixed = getattr(problem, "saddle_point", False)
        Vu = W.sub(0) if mixed else W
        self._test = fem.Function(W)
        fdim = domain.tdim - 1
        facets = domain.facets(boundary)
        self._dofs = []
        for i in range(domain.gdim):
            sub = Vu.sub(i)
            collapsed = sub.collapse()[0]
            self._dofs.append(fem.locate_dofs_topological((sub, collapsed), fdim, facets)[0])
        self._form = fem.form(ufl.derivative(problem.energy_internal, problem.u, self._test))

    def __call__(self) -> np.ndarray:
        """The force vector (all ranks get the same values)."""
        out = np.zeros(len(self._dofs))
        for i, dofs in enumerate(self._dofs):
            self._test.x.array[:] = 0.0
            self._test.x.array[dofs] = 1.0
            out[i] = fem.assemble_scalar(self._form)
        return self.comm.allreduce(out)
