r"""Three-field (Hu–Washizu) formulation for nearly incompressible solids.

With the energy split :math:`\psi = \psi_\text{iso}(F) + U(J)` the unknowns are the
displacement :math:`u`, a pressure :math:`p` and a volume ratio :math:`\theta`
(Simo, Taylor & Pister 1985), and

.. math::
    \Pi(u, p, \theta) = \sum_r \int_{\Omega_r} \Big[\psi_{\text{iso},r}(F) + U_r(\theta)
        + p\,(J - \theta)\Big]\,dX - W_\text{dead}(u)

is made stationary over :math:`P_2` displacements and :math:`P_1` pressure and
volume (by default; Taylor–Hood plus a volume field in the pressure space).
Stationarity in :math:`p` makes :math:`\theta` the :math:`L^2` projection of
:math:`J`, and in :math:`\theta` makes :math:`p` the projection of
:math:`U'(\theta)`; eliminating both pointwise gives back :math:`\psi_\text{iso} +
U(J)`. The constraint is *linear* in :math:`J`, so the constant test function
keeps :math:`\int_\Omega J\,dX = \int_\Omega\theta\,dX` exactly, and :math:`U` is
evaluated on the smooth :math:`\theta`; any volumetric law works. For
:math:`U = \frac{K}{2}(J-1)^2` it is algebraically the u–p form
:math:`\int\psi_\text{iso} + p(J-1) - p^2/(2K)`.

The previous two-field form :math:`\int\psi_\text{iso} + p\ln J - p^2/(2K)` tested
:math:`\ln J = p/K` only against the :math:`P_1` pressures, so :math:`J` could
oscillate inside the cells at unchanged :math:`\int q\ln J` while, :math:`\ln` being
concave, :math:`\int J` grew: volume came for free and lowered the isochoric
energy of a stretched body. At stretch 2 the homogeneous state of a 4×4×4 cube
was a saddle of that discrete problem, and Newton converged to a lower,
non-homogeneous state with :math:`\int J\,dX = 1.07` (:math:`K/\mu = 10^3`).

:class:`MixedHyperelasticProblem` satisfies the solver protocol of
:class:`~hyperfem.solver.NewtonSolver`: ``u`` is the *mixed* function
:math:`w = (u, p, \theta - 1)` (the volume block stores the dilatation, so
:math:`w = 0` is the reference state), the displacement is
:attr:`~MixedHyperelasticProblem.displacement_field` (call
:meth:`~MixedHyperelasticProblem.update_fields`). Residual and tangent are
``ufl.derivative`` of :math:`\Pi`. Because :math:`\Pi` is a saddle point in
:math:`p`, it cannot be a line-search merit function, so the problem reports
``conservative = False`` and the solver uses a residual-based line search.
:meth:`~MixedHyperelasticProblem.check_solution` flags converged states whose
:math:`J` is far from its projection :math:`\theta` (see
:data:`VOLUME_CONSISTENCY_LIMIT`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import basix.ufl
import numpy as np
import ufl
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.materials.viscoelastic import Viscoelastic
from hyperfem.materials.volumetric import volumetric_law
from hyperfem.mesh.domain import Domain
from hyperfem.problem.boundary_conditions import BoundaryCondition, _CompiledDirichlet
from hyperfem.problem.hyperelastic import HyperelasticProblem, default_quadrature_degree
from hyperfem.problem.base import EnergyProblem
from hyperfem.problem.energy import check_energy_callable, check_region_coverage
from hyperfem.problem.loads import Load
from hyperfem.problem.quadrature import check_volume_quadrature
from hyperfem.validation import check_positive

__all__ = [
    "VOLUME_CONSISTENCY_LIMIT",
    "MixedHyperelasticProblem",
    "SplitEnergy",
    "solid_problem",
]

Expr = ufl.core.expr.Expr

VOLUME_CONSISTENCY_LIMIT = 0.1
r"""Largest accepted :math:`\eta = \big(\int(J - \theta)^2\,dX / \int dX\big)^{1/2}` of a converged state.

Measured on correct solutions: :math:`< 10^{-9}` for homogeneous stretch and
compression of a cube (any mesh, any law); 0.020 (0.012, 0.006 on meshes 2×
and 4× finer) for the gripped bar of ``tests/test_mixed.py`` at stretch 1.2,
0.046 for the same bar at stretch 2 (0.029 on 12×2×2), which is dominated by
the singular grip edge; up to 0.023 in the muscle demo (0.034 with ``--h
0.008``). On the spurious states of the old two-field :math:`\ln J` form at
stretch 2: 0.41 (4×4×4), 0.34 (8×8×8), with :math:`J` projected onto the
volume space. The limit sits a factor of two above the largest correct value
and a factor of three below the smallest spurious one. In between: 0.098 for
a cube compressed to 0.5 on 4×4×4 that left the homogeneous branch past its
(physical) stability limit, a buckled state the mesh cannot resolve.
"""


@dataclass(frozen=True)
class SplitEnergy:
    r"""An energy split into isochoric and volumetric parts, :math:`\psi_\text{iso}(F) + U(J)`.

    Attributes:
        isochoric: :math:`\psi_\text{iso}(F)` (a function of the deformation gradient).
        bulk_modulus: :math:`K > 0`.
        volumetric: Volumetric law name (any of
            :data:`~hyperfem.materials.volumetric.VOLUMETRIC_LAWS`).
        shear_modulus: The small-strain shear modulus of the isochoric part where it is known
            (``OgdenParameters.shear_modulus``), or ``None``: then
            :meth:`MixedHyperelasticProblem.reference_shear_moduli` derives it from
            :math:`\partial^2\psi_\text{iso}/\partial F^2` at :math:`I`, a form to compile (measured:
            4 s for three Ogden terms on a loaded 2-core machine).
    """

    isochoric: Callable[[Expr], Expr]
    bulk_modulus: float
    volumetric: str = "log"
    shear_modulus: float | None = None

    def __post_init__(self) -> None:
        check_positive("bulk_modulus", self.bulk_modulus, "SplitEnergy")
        if self.shear_modulus is not None:
            check_positive("shear_modulus", self.shear_modulus, "SplitEnergy")
        check_energy_callable(self.isochoric, "SplitEnergy isochoric part")
        volumetric_law(self.volumetric)

    def volumetric_energy(self, J: Expr) -> Expr:
        """:math:`U(J)` of the volumetric law (``J`` may be :math:`\\det F` or the volume field :math:`\\theta`)."""
        return volumetric_law(self.volumetric).energy(J, self.bulk_modulus)

    def energy(self, F: Expr) -> Expr:
        """The full energy :math:`\\psi(F) = \\psi_\\text{iso}(F) + U(\\det F)` (displacement formulation)."""
        return self.isochoric(F) + self.volumetric_energy(ufl.det(F))

    def mixed_energy(self, F: Expr, p: Expr, theta: Expr) -> Expr:
        r"""Three-field density :math:`\psi_\text{iso}(F) + U(\theta) + p\,(\det F - \theta)`.

        At fixed :math:`p, \theta` its derivative in :math:`F` is the first
        Piola–Kirchhoff stress :math:`\partial_F\psi_\text{iso} + p\,\operatorname{cof}F`.
        """
        return self.isochoric(F) + self.volumetric_energy(theta) + p * (ufl.det(F) - theta)


class MixedHyperelasticProblem(EnergyProblem):
    r"""Three-field :math:`(u, p, \theta)` problem of a nearly incompressible body.

    Args:
        domain: Mesh with named groups.
        material: A :class:`SplitEnergy` or a :class:`~hyperfem.materials.Viscoelastic`
            one (its isochoric part relaxes, :math:`U(\theta)` stays elastic; the problem
            binds its history to :attr:`F` and its volume rule and moves it in
            :meth:`set_time`), or a mapping region name → either (every cell must
            belong to one region).
        bcs: Displacement Dirichlet conditions (by boundary name).
        loads: External loads (dead and follower), as for
            :class:`~hyperfem.problem.HyperelasticProblem`.
        degree: Displacement degree (default 2).
        pressure_degree: Degree of the pressure and the volume field (default
            ``degree - 1``; Taylor–Hood).
        quadrature_degree: Default :func:`~hyperfem.problem.default_quadrature_degree` of ``degree`` and
            the cell type (Q2 on hexahedra: 3 × 3 × 3 Gauss points).
        updaters: Objects with ``update(t)`` called by :meth:`set_time`
            (e.g. :class:`~hyperfem.loading.Activation`).

    Attributes:
        u: The mixed unknown :math:`w = (u, p, \theta - 1)` (what the solver updates).
        displacement_field, pressure, volume: Collapsed copies of :math:`u, p, \theta`,
            refreshed by :meth:`update_fields`.
        F: Deformation gradient (UFL, from the displacement block).
        p: Pressure (UFL, from the pressure block).
        theta: Volume ratio :math:`\theta` (UFL, one plus the volume block).
    """

    saddle_point = True

    _shear_moduli: dict[str | None, float] | None = None  # filled by reference_shear_moduli()

    def __init__(
        self,
        domain: Domain,
        material: SplitEnergy | Viscoelastic | Mapping[str, SplitEnergy | Viscoelastic],
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
        regions: dict[str | None, SplitEnergy | Viscoelastic]
        if isinstance(material, (SplitEnergy, Viscoelastic)):
            regions = {None: material}
        elif not isinstance(material, Mapping) or not material:
            what = "material mapping is empty" if isinstance(material, Mapping) else (
                f"material must be a SplitEnergy, a Viscoelastic or a mapping region -> either, "
                f"got {type(material).__name__}")
            raise ParameterError(f"MixedHyperelasticProblem: {what}")
        else:
            regions = {name: m for name, m in material.items()}
            check_region_coverage(domain, list(material), "MixedHyperelasticProblem")
        for name, m in regions.items():
            if not isinstance(m, (SplitEnergy, Viscoelastic)):
                raise ParameterError(
                    f"MixedHyperelasticProblem: the material of {name!r} must be a SplitEnergy or a Viscoelastic, "
                    f"got {type(m).__name__}"
                )
        self.domain = domain
        mesh = domain.mesh
        gdim = domain.gdim
        self.degree = degree
        self.pressure_degree = pressure_degree
        self.quadrature_degree = quadrature_degree or default_quadrature_degree(degree, mesh.topology.cell_type)
        check_volume_quadrature(degree, self.quadrature_degree, mesh.topology.cell_type, "MixedHyperelasticProblem")
        md = {"quadrature_degree": self.quadrature_degree}
        self._check_domain(domain, [(gdim, degree), (1, pressure_degree), (1, pressure_degree)], self.quadrature_degree)
        cell = mesh.basix_cell()
        el_u = basix.ufl.element("Lagrange", cell, degree, shape=(gdim,))
        el_p = basix.ufl.element("Lagrange", cell, pressure_degree)
        self.W = fem.functionspace(mesh, basix.ufl.mixed_element([el_u, el_p, el_p]))
        self.u = fem.Function(self.W, name="state")
        self.V, self._u_dofs = self.W.sub(0).collapse()
        self.Q, self._p_dofs = self.W.sub(1).collapse()
        Q_theta, self._theta_dofs = self.W.sub(2).collapse()
        self.displacement_field = fem.Function(self.V, name="displacement")
        self.pressure = fem.Function(self.Q, name="pressure")
        self.volume = fem.Function(Q_theta, name="volume_ratio")
        u, p, dilatation = ufl.split(self.u)
        v = ufl.TestFunction(self.W)
        v_u = ufl.split(v)[0]
        dw = ufl.TrialFunction(self.W)
        self.p = p
        self.theta = 1.0 + dilatation
        self.F = ufl.Identity(gdim) + ufl.grad(u)
        updaters = list(updaters)
        for m in regions.values():  # a viscoelastic history on the volume rule, moved by set_time
            if isinstance(m, Viscoelastic):
                m.bind(self.F, self.quadrature_degree)
                updaters += [h for h in m.updaters if not any(h is other for other in updaters)]

        def dx(name: str | None) -> ufl.Measure:
            return domain.dx(name, metadata=md)

        self.energy_internal = sum(m.mixed_energy(self.F, p, self.theta) * dx(n) for n, m in regions.items())
        J = ufl.det(self.F)
        # What check_solution assembles (compiled on first use).
        self._check_integrands = (
            (J - self.theta) ** 2 * dx(None),
            sum(m.energy(self.F) * dx(n) for n, m in regions.items()),
        )
        self._check_forms: tuple[fem.Form, ...] | None = None
        self.material = material
        self._regions = regions
        self._md = md
        self._dirichlet = [_CompiledDirichlet(bc, self.W.sub(0), domain) for bc in bcs]

        # Pi is stationary, not minimal, in p: never use it as a line-search merit.
        self._derive_forms(u, v, v_u, dw, loads, conservative=False, updaters=updaters)

    def update_fields(self) -> tuple[fem.Function, fem.Function]:
        """Copy the blocks into :attr:`displacement_field`, :attr:`pressure` and :attr:`volume` (:math:`\\theta`).

        Returns:
            ``(displacement, pressure)``.
        """
        self.displacement_field.x.array[:] = self.u.x.array[self._u_dofs]
        self.pressure.x.array[:] = self.u.x.array[self._p_dofs]
        self.volume.x.array[:] = 1.0 + self.u.x.array[self._theta_dofs]
        return self.displacement_field, self.pressure

    def displacement(self, state: fem.Function | None = None) -> Expr:
        """The displacement block of ``state`` (default :attr:`u`), a function on :attr:`W`."""
        return ufl.split(self.u if state is None else state)[0]

    def displacement_space(self) -> fem.FunctionSpace:
        """The displacement subspace ``W.sub(0)``."""
        return self.W.sub(0)

    def field_dofs(self) -> dict[str, np.ndarray]:
        """Local indices into :attr:`u`'s array of each field (owned and ghost dofs).

        Keys ``"displacement"`` (in the order of the collapsed displacement
        space, component fastest), ``"pressure"`` and ``"volume"``.
        """
        return {
            "displacement": np.asarray(self._u_dofs, dtype=np.int64).reshape(-1),
            "pressure": np.asarray(self._p_dofs, dtype=np.int64).reshape(-1),
            "volume": np.asarray(self._theta_dofs, dtype=np.int64).reshape(-1),
        }

    def reference_shear_moduli(self) -> dict[str | None, float]:
        r"""Small-strain shear modulus :math:`\mu_r` of each region's isochoric energy (at :math:`F = I`).

        :math:`2\mu = \frac{1}{n}\sum_{k=1}^{n} D_k : \frac{\partial^2\psi_\text{iso}}{\partial F^2}(I) : D_k`
        over an orthonormal basis :math:`D_k` of the symmetric deviatoric tensors
        (:math:`n = 5` in 3D, 2 in 2D), averaged over the region (fibre fields
        make it vary). Exact for an isotropic law (:math:`\mu` of its
        linearisation), the mean over shear modes for an anisotropic one.
        Collective; each region's small form is compiled on first use, unless its
        :class:`SplitEnergy` gives its ``shear_modulus``, which is taken as it is.
        """
        if self._shear_moduli is None:
            d = self.domain.gdim
            basis = _deviatoric_basis(d)
            F = ufl.variable(ufl.Identity(d))
            i, j, p, q = ufl.indices(4)
            moduli: dict[str | None, float] = {}
            for name, material in self._regions.items():
                m = material.elastic if isinstance(material, Viscoelastic) else material  # its instantaneous law
                if m.shear_modulus is not None:
                    moduli[name] = float(m.shear_modulus)
                    continue
                A = ufl.diff(ufl.diff(m.isochoric(F), F), F)
                two_mu = sum(ufl.as_matrix(D)[i, j] * A[i, j, p, q] * ufl.as_matrix(D)[p, q] for D in basis)
                two_mu = two_mu / len(basis)
                dx = self.domain.dx(name, metadata=self._md)
                local = np.array(
                    [
                        fem.assemble_scalar(fem.form(0.5 * two_mu * dx)),
                        fem.assemble_scalar(fem.form(fem.Constant(self.domain.mesh, 1.0) * dx)),
                    ]
                )
                integral, measure = self.domain.comm.allreduce(local)
                moduli[name] = float(integral / measure)
            self._shear_moduli = moduli
        return dict(self._shear_moduli)

    def schur_preconditioner_term(self) -> ufl.Form:
        r"""The pressure block added to the tangent to precondition its Schur complement.

        Eliminating :math:`u` from the linearised three-field system leaves, in
        the :math:`(p, \theta)` unknowns,
        :math:`S = \begin{pmatrix} -B K_{uu}^{-1} B^T & -M \\ -M & H \end{pmatrix}`
        (:math:`B` the linearised :math:`\int q\,\delta J`, :math:`M` the
        :math:`p`–:math:`\theta` mass matrix, :math:`H = \int U''(\theta)\,\eta\,\hat\theta`).
        :math:`K_{uu}` is the isochoric (shear) stiffness, so
        :math:`B K_{uu}^{-1} B^T` is spectrally equivalent to the pressure mass
        matrix over the shear modulus, uniformly in :math:`h` and in :math:`K/\mu`
        (the Stokes argument). This returns
        :math:`-\sum_r \mu_r^{-1}\int_{\Omega_r} p\,q\,dX` (see
        :meth:`reference_shear_moduli`); the tangent plus this term is the
        preconditioning matrix whose :math:`(p,\theta)` block is the Schur approximation.
        """
        p_hat = ufl.split(ufl.TrialFunction(self.W))[1]
        q = ufl.split(ufl.TestFunction(self.W))[1]
        return sum(
            -(1.0 / mu) * p_hat * q * self.domain.dx(name, metadata=self._md)
            for name, mu in self.reference_shear_moduli().items()
        )

    def volume_jacobian(self) -> Expr:
        r""":math:`\min(J, \theta)`, so the solver's inversion guard keeps both positive.

        :math:`U(\theta)` may need :math:`\ln\theta`, and a Newton step can shrink
        :math:`\theta` through zero while :math:`J` stays positive.
        """
        return ufl.min_value(ufl.det(self.F), self.theta)

    def check_solution(self) -> tuple[dict[str, float], str | None]:
        r"""Consistency of a converged state: is :math:`J` resolved by its projection :math:`\theta`?

        Indicators:

        * ``volume_consistency`` :math:`\eta = \big(\int (J - \theta)^2\,dX / \int dX\big)^{1/2}`:
          the pointwise distance of :math:`J` from its :math:`P_1` projection,
          large when :math:`J` oscillates inside the cells (the spurious states
          of the old two-field form had 0.34–0.41). Above
          :data:`VOLUME_CONSISTENCY_LIMIT` the state is rejected.
        * ``energy_gap``: :math:`(E_u - \Pi_\text{int}) / \max(|E_u|, |\Pi_\text{int}|)` with
          the displacement energy :math:`E_u = \int\psi_\text{iso} + U(J)` on the same
          state. Recorded, not checked: it is about :math:`\frac{K}{2}\eta^2|\Omega|/E_u` and
          does not discriminate (0.78 on the correct gripped bar, 0.87 on the
          spurious cube).

        Returns:
            ``(indicators, message)``; ``message`` is ``None`` when the state is accepted.
        """
        if self._check_forms is None:
            self._check_forms = tuple(fem.form(f) for f in (*self._check_integrands, self.energy_internal))
            one = fem.form(fem.Constant(self.domain.mesh, 1.0) * self.domain.dx())
            self._measure = self.domain.comm.allreduce(fem.assemble_scalar(one))
        local = np.array([fem.assemble_scalar(f) for f in self._check_forms], dtype=float)
        mismatch, displacement_energy, mixed = self.domain.comm.allreduce(local)
        eta = math.sqrt(max(mismatch, 0.0) / self._measure)
        scale = max(abs(displacement_energy), abs(mixed))
        gap = (displacement_energy - mixed) / scale if scale > 0.0 else 0.0
        indicators = {"volume_consistency": eta, "energy_gap": gap}
        if not eta <= VOLUME_CONSISTENCY_LIMIT:
            return indicators, (
                f"J is not resolved by the volume field: ||J - theta|| / |Omega|^(1/2) = {eta:.3g} "
                f"> {VOLUME_CONSISTENCY_LIMIT:g} (refine the mesh or reduce the load step)"
            )
        return indicators, None


def _deviatoric_basis(d: int) -> list[np.ndarray]:
    """An orthonormal basis (Frobenius product) of the symmetric traceless d×d tensors."""
    basis = []
    for a in range(d):
        for b in range(a + 1, d):
            D = np.zeros((d, d))
            D[a, b] = D[b, a] = 1.0 / math.sqrt(2.0)
            basis.append(D)
    diagonal = [np.diag(v) for v in ([1.0, -1.0, 0.0][:d], [1.0, 1.0, -2.0][:d])][: d - 1]
    basis.extend(D / np.linalg.norm(D) for D in diagonal)
    return basis


def solid_problem(
    domain: Domain,
    material: SplitEnergy | Viscoelastic | Mapping[str, SplitEnergy | Viscoelastic],
    *,
    formulation: str = "mixed",
    degree: int | None = None,
    **kwargs: Any,
) -> HyperelasticProblem | MixedHyperelasticProblem:
    """Build the problem of a split energy in the chosen formulation.

    Args:
        domain: Mesh with named groups.
        material: Split energy or a viscoelastic one (or mapping region → either).
        formulation: ``"mixed"`` (Taylor–Hood u–p) or ``"displacement"``.
        degree: Displacement degree (default 2 for mixed, 1 for displacement).
        **kwargs: Passed on (``bcs``, ``loads``, ``quadrature_degree``, ``updaters``...).
    """
    if formulation == "mixed":
        return MixedHyperelasticProblem(domain, material, degree=degree or 2, **kwargs)
    if formulation == "displacement":

        def energy(m: SplitEnergy | Viscoelastic) -> Callable[[Expr], Expr]:
            return m if isinstance(m, Viscoelastic) else m.energy  # a Viscoelastic itself: its history is bound

        psi = energy(material) if isinstance(material, (SplitEnergy, Viscoelastic)) else {
            k: energy(m) for k, m in material.items()}
        return HyperelasticProblem(domain, psi, degree=degree or 1, **kwargs)
    raise ParameterError(f"unknown formulation {formulation!r} (use 'mixed' or 'displacement')")
