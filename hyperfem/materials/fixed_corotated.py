r"""Fixed-corotated and as-rigid-as-possible (ARAP) energies (seed 004), invertible.

.. math::
    \psi_\text{FC}(F) = \mu\,\|F - R(F)\|^2 + \frac{\lambda}{2}(J - 1)^2,\qquad
    \psi_\text{ARAP}(F) = \mu\,\|F - R(F)\|^2 = \mu \sum_i (\sigma_i - 1)^2,

with :math:`R(F)` the rotation of the polar decomposition (rotation-variant
SVD, :mod:`hyperfem.materials.polar`), so inverted elements have finite,
restoring energy. Linearised at :math:`F = I` (:math:`\delta R = \operatorname{skew}\delta F`)
the fixed-corotated stress is :math:`2\mu\varepsilon + \lambda\operatorname{tr}(\varepsilon) I`:
consistent with linear elasticity for the same Lamé pair (ARAP: for
:math:`\lambda = 0`).

**Design.** :math:`R(F)` is not a UFL expression. It is held in a quadrature
field (:class:`~hyperfem.materials.polar.RotationField`) that
:meth:`PolarRotationEnergy.refresh` recomputes from the current :math:`F`;
the solver must call it at every new state before assembling a residual,
tangent or energy (the material lists it in ``state_hooks``, which
:class:`~hyperfem.problem.HyperelasticProblem` collects and
:class:`~hyperfem.solver.NewtonSolver` runs). With :math:`R` refreshed:

* **energy** — exact;
* **stress** — exact: :math:`R` is the closest rotation, so
  :math:`(F - R) : \delta R = \operatorname{tr}((S - I)\,W) = 0` for every
  admissible :math:`\delta R = R W` (:math:`W` skew, :math:`S` symmetric) and
  :math:`\partial_F \|F - R(F)\|^2 = 2(F - R)`: what ``ufl.derivative``
  gives with :math:`R` frozen;
* **tangent** — with :math:`R` frozen ``ufl.derivative`` misses
  :math:`-2\mu\,\partial R/\partial F`. With ``exact_tangent=True`` (default)
  :math:`T = \partial R/\partial F` (closed form from the SVD,
  :func:`~hyperfem.materials.polar.rotation_derivative`) is held in a second
  quadrature field and the material offers
  :meth:`PolarRotationEnergy.tangent_correction`, the pseudo-energy
  :math:`c(F) = -\mu\,F : T : F` whose second variation
  :math:`-2\mu\,\nabla\delta u : T : \nabla v` the problem adds to its
  tangent only. ``exact_tangent=False`` keeps the frozen-:math:`R` tangent
  (:math:`2\mu\mathbb{I} + \dots`, always positive for the shear part, but
  Newton converges only linearly).

The frozen exact tangent is not positive definite in strong compression
(:math:`\sigma_i + \sigma_j < 2` gives negative twist modes, seed 004's
:math:`B_{ij}`); the line search copes on the tested cases.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import ufl

from hyperfem.errors import ParameterError
from hyperfem.kinematics import cofactor
from hyperfem.materials.parameters import LameParameters
from hyperfem.materials.polar import RotationField
from hyperfem.validation import check_positive

__all__ = [
    "ARAP",
    "FixedCorotated",
    "PolarRotationEnergy",
    "arap",
    "arap_stress",
    "fixed_corotated",
    "fixed_corotated_stress",
]


def fixed_corotated(F: ufl.core.expr.Expr, R: ufl.core.expr.Expr, params: LameParameters) -> ufl.core.expr.Expr:
    r""":math:`\mu\|F - R\|^2 + \tfrac{\lambda}{2}(\det F - 1)^2` for a given rotation ``R``."""
    return params.mu * ufl.inner(F - R, F - R) + 0.5 * params.lmbda * (ufl.det(F) - 1.0) ** 2


def fixed_corotated_stress(
    F: ufl.core.expr.Expr, R: ufl.core.expr.Expr, params: LameParameters
) -> ufl.core.expr.Expr:
    r"""Closed-form :math:`P = 2\mu(F - R) + \lambda(J - 1)\operatorname{cof} F` (``R`` = polar rotation of ``F``)."""
    return 2.0 * params.mu * (F - R) + params.lmbda * (ufl.det(F) - 1.0) * cofactor(F)


def arap(F: ufl.core.expr.Expr, R: ufl.core.expr.Expr, mu: float) -> ufl.core.expr.Expr:
    r""":math:`\mu\|F - R\|^2` for a given rotation ``R``."""
    return mu * ufl.inner(F - R, F - R)


def arap_stress(F: ufl.core.expr.Expr, R: ufl.core.expr.Expr, mu: float) -> ufl.core.expr.Expr:
    r"""Closed-form :math:`P = 2\mu(F - R)` (``R`` = polar rotation of ``F``)."""
    return 2.0 * mu * (F - R)


class PolarRotationEnergy(ABC):
    """An energy :math:`\\psi(F, R(F))` with the polar rotation held in quadrature fields.

    Callable as ``psi(F)``. The first call binds the fields to that ``F``
    (mesh and points; see :meth:`bind`); one object serves one problem.

    Args:
        quadrature_degree: Degree of the volume rule the energy is integrated
            with; default: that of the problem
            (:class:`~hyperfem.problem.HyperelasticProblem` binds it) or
            :func:`~hyperfem.problem.default_quadrature_degree`.
        exact_tangent: Hold :math:`\\partial R/\\partial F` and offer
            :meth:`tangent_correction` (module docstring).

    Attributes:
        invertible: ``True``.
        field: The :class:`~hyperfem.materials.polar.RotationField`.
    """

    invertible = True
    updaters: tuple = ()
    """No updaters: the rotation follows every state through :attr:`state_hooks`."""
    _name = "PolarRotationEnergy"

    def __init__(self, *, quadrature_degree: int | None = None, exact_tangent: bool = True):
        if quadrature_degree is not None and not (
            isinstance(quadrature_degree, int) and not isinstance(quadrature_degree, bool) and quadrature_degree >= 1
        ):
            raise ParameterError(
                f"{self._name}: quadrature_degree must be an integer >= 1 or None, got {quadrature_degree!r}"
            )
        self.quadrature_degree = quadrature_degree
        self.exact_tangent = bool(exact_tangent)
        self.field = RotationField(derivative=self.exact_tangent, name=self._name)

    # -- what the problem and the solver use --------------------------------
    def bind(self, F: ufl.core.expr.Expr, quadrature_degree: int | None = None) -> None:
        """Attach the fields to ``F`` on the rule of ``quadrature_degree`` (default: the constructor's)."""
        if quadrature_degree is not None and self.quadrature_degree not in (None, quadrature_degree):
            raise ParameterError(
                f"{self._name}: built for quadrature degree {self.quadrature_degree}, "
                f"the problem integrates with degree {quadrature_degree}"
            )
        self.field.bind(F, quadrature_degree if quadrature_degree is not None else self.quadrature_degree)

    def refresh(self) -> None:
        """Recompute :math:`R` (and :math:`\\partial R/\\partial F`) from the current state."""
        self.field.refresh()

    @property
    def state_hooks(self) -> tuple:
        """Callables to run at every new state before assembly: ``(refresh,)``."""
        return (self.refresh,)

    @property
    def quadrature_rule_degree(self) -> int | None:
        """Degree of the volume rule the fields sit on; ``None``: any rule (cellwise-constant fields, or unbound)."""
        return self.field.rule_degree

    @property
    def rotation(self) -> ufl.core.expr.Expr:
        """The rotation field in UFL (bound first)."""
        if self.field.rotation is None:
            raise ParameterError(f"{self._name}: not bound to a deformation gradient yet (call it with F first)")
        return self.field.rotation.function

    def __call__(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        self.bind(F)
        return self.energy(F, self.rotation)

    def stress(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Closed-form :math:`P` with the current rotation field (verification only)."""
        self.bind(F)
        return self.closed_form_stress(F, self.rotation)

    def tangent_correction(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr | None:
        r"""Pseudo-energy :math:`-\mu\,F : T : F` whose second variation completes the frozen-:math:`R` tangent.

        Only its second derivative is meaningful: it is added to the tangent,
        never to the energy or the residual. ``None`` without ``exact_tangent``.
        """
        if not self.exact_tangent:
            return None
        self.bind(F)
        assert self.field.derivative is not None  # bound with derivative=exact_tangent
        T = self.field.derivative.function
        i, j, k, l = ufl.indices(4)  # noqa: E741
        return -self.shear_modulus * T[i, j, k, l] * F[i, j] * F[k, l]

    # -- the law -------------------------------------------------------------
    shear_modulus: float

    @abstractmethod
    def energy(self, F: ufl.core.expr.Expr, R: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """The energy density for deformation gradient ``F`` and rotation ``R``."""

    @abstractmethod
    def closed_form_stress(self, F: ufl.core.expr.Expr, R: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """The first Piola–Kirchhoff stress for ``F`` and its polar rotation ``R``."""


class FixedCorotated(PolarRotationEnergy):
    r"""Fixed-corotated energy :math:`\mu\|F - R\|^2 + \tfrac{\lambda}{2}(J - 1)^2` (module docstring).

    Args:
        params: Lamé parameters.
        quadrature_degree, exact_tangent: See :class:`PolarRotationEnergy`.
    """

    _name = "FixedCorotated"

    def __init__(self, params: LameParameters, *, quadrature_degree: int | None = None, exact_tangent: bool = True):
        if not isinstance(params, LameParameters):
            raise ParameterError(f"FixedCorotated: params must be LameParameters, got {type(params).__name__}")
        self.params = params
        self.shear_modulus = params.mu
        super().__init__(quadrature_degree=quadrature_degree, exact_tangent=exact_tangent)

    def energy(self, F: ufl.core.expr.Expr, R: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """:func:`fixed_corotated` with rotation ``R``."""
        return fixed_corotated(F, R, self.params)

    def closed_form_stress(self, F: ufl.core.expr.Expr, R: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """:func:`fixed_corotated_stress` with rotation ``R``."""
        return fixed_corotated_stress(F, R, self.params)


class ARAP(PolarRotationEnergy):
    r"""As-rigid-as-possible energy :math:`\mu\|F - R\|^2 = \mu\sum_i(\sigma_i - 1)^2` (seed 004).

    Args:
        mu: Shear modulus :math:`\mu > 0`, or :class:`LameParameters` (its
            :math:`\lambda` is not used: ARAP has no separate volume term).
        quadrature_degree, exact_tangent: See :class:`PolarRotationEnergy`.
    """

    _name = "ARAP"

    def __init__(
        self, mu: float | LameParameters, *, quadrature_degree: int | None = None, exact_tangent: bool = True
    ):
        mu = mu.mu if isinstance(mu, LameParameters) else mu
        check_positive("mu", mu, "ARAP")
        self.shear_modulus = float(mu)
        super().__init__(quadrature_degree=quadrature_degree, exact_tangent=exact_tangent)

    def energy(self, F: ufl.core.expr.Expr, R: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """:func:`arap` with rotation ``R``."""
        return arap(F, R, self.shear_modulus)

    def closed_form_stress(self, F: ufl.core.expr.Expr, R: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """:func:`arap_stress` with rotation ``R``."""
        return arap_stress(F, R, self.shear_modulus)
