r"""Corotational linear elasticity (COR, warped stiffness; seed 003 §3, seed 004), invertible.

.. math::
    \Psi_\text{LC}(F) = \Psi_\text{lin}\bigl((R^n)^T F\bigr),\qquad
    P = R^n\,\sigma_\text{lin}\bigl((R^n)^T F\bigr),

with :math:`\Psi_\text{lin}` small-strain elasticity
(:func:`~hyperfem.materials.linear_elastic`) and :math:`R^n` the polar
rotation of :math:`F` at the *start* of the load or time step, held fixed
during the step. Within a step the energy is quadratic in :math:`F`, so
``ufl.derivative`` gives its exact stress and tangent; between steps the
rotation follows the body, so a rigid rotation carried over a step is
stress free at the next one (small-strain elasticity alone stores
:math:`2(\mu + \lambda)(1 - \cos\theta)^2` per unit volume, per rotated plane).

**Binding.** :math:`R^n` lives in a quadrature field
(:class:`~hyperfem.materials.polar.RotationField`) bound to the deformation
gradient the energy is first called with (the problem's :math:`F`). The
:class:`StepRotation` updater recomputes it from the current state;
:class:`~hyperfem.problem.HyperelasticProblem` calls updaters from
``set_time`` — at the start of each load or time step, with the last
accepted state in ``problem.u`` — and collects the material's own updater,
so ``corotational_linear(params)`` is all it takes::

    psi, updater = corotational_linear(params)
    problem = HyperelasticProblem(domain, psi, ..., updaters=[updater])  # updater optional
"""

from __future__ import annotations

import ufl

from hyperfem.errors import ParameterError
from hyperfem.materials.linear_elastic import linear_elastic, linear_elastic_stress
from hyperfem.materials.parameters import LameParameters
from hyperfem.materials.polar import RotationField

__all__ = [
    "CorotationalLinear",
    "StepRotation",
    "corotational_linear",
    "corotational_linear_energy",
    "corotational_linear_stress",
]


def corotational_linear_energy(
    F: ufl.core.expr.Expr, R: ufl.core.expr.Expr, params: LameParameters
) -> ufl.core.expr.Expr:
    r""":math:`\Psi_\text{lin}(R^T F)` for a given rotation ``R``."""
    return linear_elastic(R.T * F, params)


def corotational_linear_stress(
    F: ufl.core.expr.Expr, R: ufl.core.expr.Expr, params: LameParameters
) -> ufl.core.expr.Expr:
    r"""Closed-form :math:`P = R\,\sigma_\text{lin}(R^T F)` (verification only)."""
    return R * linear_elastic_stress(R.T * F, params)


class StepRotation:
    """Updater that moves the rotation :math:`R^n` of a :class:`CorotationalLinear` to the current state.

    Meets :class:`~hyperfem.problem.protocol.Updater`; ``update(t)`` ignores ``t``.
    """

    def __init__(self, material: CorotationalLinear):
        self.material = material

    def update(self, t: float) -> None:
        """:math:`R^n \\leftarrow R(F(u))` for the current ``u`` (no-op before the material is bound)."""
        if self.material.field.bound:
            self.material.field.refresh()


class CorotationalLinear:
    """Callable energy ``psi(F)`` of corotational linear elasticity (module docstring).

    Args:
        params: Lamé parameters.
        quadrature_degree: Degree of the volume rule; default: the problem's
            (:class:`~hyperfem.problem.HyperelasticProblem` binds it).

    Attributes:
        invertible: ``True``.
        field: The :class:`~hyperfem.materials.polar.RotationField` of :math:`R^n`.
        updater: Its :class:`StepRotation`.
    """

    invertible = True

    def __init__(self, params: LameParameters, *, quadrature_degree: int | None = None):
        if not isinstance(params, LameParameters):
            raise ParameterError(f"CorotationalLinear: params must be LameParameters, got {type(params).__name__}")
        if quadrature_degree is not None and not (
            isinstance(quadrature_degree, int) and not isinstance(quadrature_degree, bool) and quadrature_degree >= 1
        ):
            raise ParameterError(
                f"CorotationalLinear: quadrature_degree must be an integer >= 1 or None, got {quadrature_degree!r}"
            )
        self.params = params
        self.quadrature_degree = quadrature_degree
        self.field = RotationField(derivative=False, name="CorotationalLinear")
        self.updater = StepRotation(self)

    state_hooks: tuple = ()
    """No state hooks: :math:`R^n` moves once a step, through :attr:`updaters`."""

    def tangent_correction(self, F: ufl.core.expr.Expr) -> None:
        """None: :math:`R^n` is frozen over the step, the stress is the derivative of the energy."""
        return None

    @property
    def updaters(self) -> tuple[StepRotation]:
        """The updaters a problem must call from ``set_time``: ``(updater,)``."""
        return (self.updater,)

    def bind(self, F: ufl.core.expr.Expr, quadrature_degree: int | None = None) -> None:
        """Attach :math:`R^n` to ``F`` (computed from the current state)."""
        if quadrature_degree is not None and self.quadrature_degree not in (None, quadrature_degree):
            raise ParameterError(
                f"CorotationalLinear: built for quadrature degree {self.quadrature_degree}, "
                f"the problem integrates with degree {quadrature_degree}"
            )
        self.field.bind(F, quadrature_degree if quadrature_degree is not None else self.quadrature_degree)

    @property
    def quadrature_rule_degree(self) -> int | None:
        """Degree of the volume rule the fields sit on; ``None``: any rule (cellwise-constant fields, or unbound)."""
        return self.field.rule_degree

    @property
    def rotation(self) -> ufl.core.expr.Expr:
        """The rotation field :math:`R^n` in UFL (bound first)."""
        if self.field.rotation is None:
            raise ParameterError("CorotationalLinear: not bound to a deformation gradient yet (call it with F first)")
        return self.field.rotation.function

    def __call__(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        self.bind(F)
        return corotational_linear_energy(F, self.rotation, self.params)

    def stress(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        """Closed-form :math:`P` with the current :math:`R^n` (verification only)."""
        self.bind(F)
        return corotational_linear_stress(F, self.rotation, self.params)


def corotational_linear(
    params: LameParameters, *, quadrature_degree: int | None = None
) -> tuple[CorotationalLinear, StepRotation]:
    """The COR energy and its step updater: ``psi, updater = corotational_linear(params)``.

    Args:
        params: Lamé parameters.
        quadrature_degree: See :class:`CorotationalLinear`.

    Returns:
        ``(psi, updater)``: pass ``psi`` as the material and (optionally:
        the problem collects it) ``updater`` among the ``updaters``.
    """
    psi = CorotationalLinear(params, quadrature_degree=quadrature_degree)
    return psi, psi.updater
