r"""Finite-strain viscoelasticity: a Prony series on the isochoric part, each step an incremental potential.

**Model** (Simo 1987; Holzapfel & Gasser 2001; Holzapfel, *Nonlinear Solid
Mechanics*, §6.10). Around any split law :math:`\psi = U(J) + \psi_\text{iso}(F)`
(a :class:`~hyperfem.problem.SplitEnergy`), the second Piola–Kirchhoff stress
is

.. math::
    S = S_\text{vol} + g_\infty S_\text{iso} + \sum_{i=1}^{N} Q_i,\qquad
    Q_i(t) = g_i \int_0^t e^{-(t-s)/\tau_i}\,\dot S_\text{iso}(s)\,ds,

with :math:`S_\text{iso} = 2\,\partial\psi_\text{iso}/\partial C` and the
:class:`~hyperfem.materials.prony.PronySeries` :math:`(g_i, \tau_i)`: the
isochoric stress relaxes by :math:`g(t) = g_\infty + \sum_i g_i e^{-t/\tau_i}`,
the volumetric one does not. The body is taken at rest (no history) at the
time of the first :meth:`~hyperfem.problem.HyperelasticProblem.set_time`.

**One step** :math:`t_n \to t_{n+1} = t_n + \Delta t`. Taking
:math:`S_\text{iso}` linear in time within the step makes the convolution
exact (:meth:`~hyperfem.materials.prony.PronySeries.step_factors`):

.. math::
    Q_i^{n+1} = c_i Q_i^n + g_i a_i\,\bigl(S_\text{iso}^{n+1} - S_\text{iso}^n\bigr),\qquad
    c_i = e^{-\Delta t/\tau_i},\quad a_i = \tfrac{\tau_i}{\Delta t}\bigl(1 - c_i\bigr),

so, with the history :math:`(Q_i^n, S_\text{iso}^n)` frozen,

.. math::
    S^{n+1} = S_\text{vol}(C) + \gamma\,S_\text{iso}(C) + B_n,\qquad
    \gamma = g_\infty + \sum_i g_i a_i,\qquad
    B_n = \sum_i \bigl(c_i Q_i^n - g_i a_i S_\text{iso}^n\bigr),

which is :math:`2\,\partial\Pi/\partial C` of the **incremental potential**

.. math::
    \Pi(C) = U(J) + \gamma\,\psi_\text{iso}(C) + \tfrac12\,B_n : C .

:class:`Viscoelastic` is that energy as a function of :math:`F`
(:math:`C = F^T F`); its first Piola–Kirchhoff stress :math:`P = F S^{n+1}` is
its UFL gradient, the tangent its ``ufl.derivative``, and each step is the
minimisation of :math:`\int\Pi\,dX - W_\text{ext}`: the energy line search, the
Taylor-tested derivatives and every solver feature apply unchanged. The
factors make the scheme exact for :math:`S_\text{iso}` linear in time and
second order in :math:`\Delta t` otherwise; it is unconditionally stable
(:math:`c_i, a_i \in (0, 1]`, :math:`\Delta t \to \infty` gives the long-term law
:math:`U + g_\infty\psi_\text{iso}`).

**History fields.** :math:`Q_i^n` and :math:`S_\text{iso}^n` are symmetric
tensors on the points of the problem's volume rule
(:class:`~hyperfem.materials.polar.QuadratureField`); :math:`c_i`,
:math:`g_i a_i` and :math:`\gamma` are :class:`dolfinx.fem.Constant` values of
the step, so nothing is recompiled. :class:`ViscousHistory` (the energy's
updater, which the problem calls from ``set_time``) moves them once per
accepted step: when the problem moves on from an accepted state it evaluates
:math:`S_\text{iso}(F)` there (a :class:`dolfinx.fem.Expression`) and applies
the recursion; when the problem goes back to an accepted time (a cut-back or
rejected step restored, the two half steps of step doubling) the history goes
back with it. A :class:`~hyperfem.simulation.Checkpoint` stores the fields and
a restart continues from them.

**Time.** ``set_time(t)`` carries the time of the loads; the physical time
is ``time_scale * t`` (``time_scale = 1``: the problem's time is in seconds,
write ramps as :class:`~hyperfem.loading.Ramp` in seconds and step to the end
time; or keep the load factor 0 → 1 and give the ramp's duration as
``time_scale``). Time must run forward (a quasi-static ramp *down* in time is
refused; unload by a profile that falls while time goes on).

**Three-field problem.** A :class:`Viscoelastic` is a material of
:class:`~hyperfem.problem.MixedHyperelasticProblem` as its split law is: the
isochoric part relaxes, the volumetric part is the problem's :math:`U(\theta)`,
and each step makes

.. math::
    \Pi(u, p, \theta) = \int U(\theta) + \gamma\,\psi_\text{iso}(F) + \tfrac12 B_n : C
        + p\,(J - \theta)\,dX

stationary (:meth:`Viscoelastic.mixed_energy`); the history sits on the
problem's volume rule and moves as above. Its stress fields
(:func:`hyperfem.simulation.measures.cauchy_stress`, case-file ``cauchy_stress`` and
``von_mises``) are the derivative of that density at the problem's :math:`p, \theta`.

**Parameters from a test.** :func:`hyperfem.materials.fit` with ``law="prony"``
(:mod:`~hyperfem.materials.prony_fit`, ``hyperfem fit RELAX.csv --law prony``) fits the
:class:`PronySeries` to relaxation data (the stress at a held strain, or :math:`g(t)`).

Supported stages: quasi-static stepping (:func:`~hyperfem.solver.solve_quasistatic`,
:class:`~hyperfem.simulation.Simulation`, with cut-backs, growth and step
doubling) and implicit dynamics whose loads are evaluated at :math:`t_{n+1}`
(backward Euler, Newmark). Not supported: generalized-α with
:math:`\alpha_f \ne 0` and explicit dynamics (they call ``set_time`` at other
than the solved times).

Usage::

    from hyperfem.materials.viscoelastic import PronySeries, Viscoelastic

    elastic = SplitEnergy(lambda F: neo_hookean_isochoric(F, mu), bulk_modulus=K)
    psi = Viscoelastic(elastic, PronySeries(g=(0.3, 0.2), tau=(0.1, 2.0)))
    problem = hf.HyperelasticProblem(domain, psi, bcs=..., loads=...)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.materials.polar import QuadratureField
from hyperfem.materials.prony import PronySeries
from hyperfem.validation import check_positive

if TYPE_CHECKING:  # hyperfem.problem imports hyperfem.materials: a run-time import would be circular
    from hyperfem.problem.mixed import SplitEnergy

__all__ = ["PronySeries", "Viscoelastic", "ViscousHistory", "isochoric_pk2"]

Expr = ufl.core.expr.Expr

_KEEP = 4
"""Accepted states the history can go back to (the step start, and the half step of step doubling)."""


def isochoric_pk2(isochoric: object, F: Expr) -> Expr:
    r"""The isochoric second Piola–Kirchhoff stress :math:`S_\text{iso} = 2\,\partial\psi_\text{iso}/\partial C`.

    Computed as :math:`\operatorname{sym}\bigl(F^{-1}\,\partial\psi_\text{iso}/\partial F\bigr)`.

    The symmetric part only: :math:`S_\text{iso}` enters through
    :math:`\tfrac12 B : C` with :math:`C` symmetric (and is symmetric for every
    objective law anyway).

    Args:
        isochoric: :math:`\psi_\text{iso}(F)`, a callable.
        F: Deformation gradient.
    """
    Fv = ufl.variable(F)
    P = ufl.diff(isochoric(Fv), Fv)  # type: ignore[operator]  # a callable, checked by SplitEnergy
    S = ufl.inv(F) * P
    return 0.5 * (S + S.T)


@dataclass
class _Accepted:
    """The history at an accepted time: the state it belongs to and the field values."""

    time: float
    state: list[np.ndarray]
    fields: list[np.ndarray]


class ViscousHistory:
    r"""The history :math:`(Q_i^n, S_\text{iso}^n)` of a :class:`Viscoelastic` energy and its step constants.

    An :class:`~hyperfem.problem.protocol.Updater`: ``update(t)`` is called by
    the problem's ``set_time`` with the unknown at the state the step starts
    from (the last accepted one, or one restored). Of the calls:

    * the first one takes the current state as the start, free of history;
    * a call at an accepted time whose state is back in the unknown (a
      restored step) returns the history to that time;
    * a call after the unknown moved (a solve at the previous time) accepts
      that state: :math:`Q_i^{n+1} = c_i Q_i^n + g_i a_i (S_\text{iso}(F) - S_\text{iso}^n)`;

    then the step's constants are set for :math:`\Delta t = \text{time\_scale}\,(t - t_n)`.
    Collective (every rank calls ``set_time``).

    For checkpoints (:mod:`hyperfem.simulation.checkpoint`) it offers
    :meth:`state_functions` and :meth:`restart`.

    Attributes:
        accepted_time: :math:`t_n`, the time of the accepted state the fields hold (problem time).
        dt: :math:`\Delta t` of the current step (physical time).
        commits: How many accepted states the history has taken in (for tests).
    """

    def __init__(self, material: Viscoelastic):
        self.material = material
        self.accepted_time: float | None = None
        self.dt = 0.0
        self.commits = 0
        self._last = 0.0
        self._accepted: list[_Accepted] = []

    @property
    def _fields(self) -> list[QuadratureField]:
        m = self.material
        assert m.Q is not None and m.S_previous is not None  # bound
        return [*m.Q, m.S_previous]

    def _state(self) -> list[np.ndarray]:
        return [f.x.array for f in self.material._functions]

    def _same_state(self, accepted: _Accepted) -> bool:
        """Whether the unknown equals that of ``accepted`` on every rank (collective)."""
        local = all(np.array_equal(a, b) for a, b in zip(self._state(), accepted.state, strict=True))
        return bool(self.material._comm.allreduce(local, op=MPI.LAND))

    def _remember(self, t: float) -> None:
        self._accepted.append(
            _Accepted(t, [a.copy() for a in self._state()], [f.function.x.array.copy() for f in self._fields])
        )
        del self._accepted[:-_KEEP]
        self.accepted_time = t

    def _go_back(self, k: int) -> None:
        self._accepted = self._accepted[: k + 1]
        entry = self._accepted[-1]
        for f, values in zip(self._fields, entry.fields, strict=True):
            f.function.x.array[:] = values
        self.accepted_time = entry.time

    def _accept(self) -> None:
        r"""Take in the current state as the state at the time of the last step: the recursion for :math:`Q_i`."""
        m = self.material
        assert m.Q is not None and m.S_previous is not None and m._S_expression is not None  # bound
        S_new = m.S_previous.evaluate(m._S_expression)
        S_old = m.S_previous.values()
        c, d = [float(k.value) for k in m._c], [float(k.value) for k in m._d]
        for i, Q in enumerate(m.Q):
            Q.assign(c[i] * Q.values() + d[i] * (S_new - S_old))
        m.S_previous.assign(S_new)
        self.commits += 1
        self._remember(self._last)

    def _set_step(self, dt: float) -> None:
        m = self.material
        c, a = m.prony.step_factors(dt)
        d = [gi * ai for gi, ai in zip(m.prony.g, a, strict=True)]
        for k, value in zip([*m._c, *m._d, m._gamma], [*c, *d, m.prony.g_inf + sum(d)], strict=True):
            k.value = value  # type: ignore[assignment]  # dolfinx: any array-like
        self.dt = dt

    def update(self, t: float) -> None:
        """Move the history to the step that ends at time ``t`` (class docstring); no-op before binding.

        Raises:
            ParameterError: ``t`` lies before the accepted time (time runs backwards).
        """
        m = self.material
        if m.Q is None:
            return
        t = float(t)
        if not self._accepted:  # the start: at rest, no history
            assert m.S_previous is not None and m._S_expression is not None  # bound
            m.S_previous.assign(m.S_previous.evaluate(m._S_expression))
            self._remember(t)
        else:
            back = [k for k, entry in enumerate(self._accepted) if entry.time == t]
            if back and self._same_state(self._accepted[back[-1]]):
                self._go_back(back[-1])
            elif not self._same_state(self._accepted[-1]):
                self._accept()
        assert self.accepted_time is not None  # set by _remember
        if t < self.accepted_time:
            raise ParameterError(
                f"{m.name}: time runs backwards: set_time({t:g}) before the accepted time {self.accepted_time:g} "
                "(a viscoelastic body is loaded forward in time; unload with a load profile that falls as time goes on)"
            )
        self._last = t
        self._set_step(m.time_scale * (t - self.accepted_time))

    # -- checkpoints --------------------------------------------------------------------
    def state_functions(self) -> dict[str, fem.Function]:
        r"""The fields of the history at the accepted state now in the unknown (collective).

        Called at an accepted state (a checkpoint after a step): a state not yet
        taken in is taken in first, so the fields belong to the current time, and
        the step's constants become those of a step of length 0
        (:math:`\gamma = 1`, :math:`B = \sum_i Q_i^{n+1} - g_i S_\text{iso}^{n+1}`), so
        the energy's stress at this state stays the model's,
        :math:`S_\text{vol} + g_\infty S_\text{iso} + \sum_i Q_i^{n+1}` (outputs after the
        checkpoint, reactions or stress fields, see the same stress as those before it).
        """
        m = self.material
        if m.Q is None or m.S_previous is None:
            return {}
        if self._accepted and not self._same_state(self._accepted[-1]):
            self._accept()
            self._set_step(0.0)
        out = {f"{m.name}_Q{i}": Q.function for i, Q in enumerate(m.Q)}
        out[f"{m.name}_S"] = m.S_previous.function
        return out

    def restart(self, t: float) -> None:
        """The fields of :meth:`state_functions` and the unknown were read back: the accepted state at ``t``."""
        if self.material.Q is None:
            return
        self._accepted = []
        self._remember(float(t))
        self._last = float(t)
        self._set_step(0.0)


class Viscoelastic:
    r"""Callable energy :math:`\Pi(F) = U(J) + \gamma\,\psi_\text{iso}(F) + \tfrac12 B_n : F^TF` (module docstring).

    Pass it as the material of a :class:`~hyperfem.problem.HyperelasticProblem`
    or a :class:`~hyperfem.problem.MixedHyperelasticProblem` (one object per
    problem): the problem binds it to its :math:`F` and volume rule and calls its
    :attr:`updaters` from ``set_time``.

    Args:
        elastic: The split law :math:`U(J) + \psi_\text{iso}(F)` (any isochoric
            part: neo-Hookean, Mooney–Rivlin, Yeoh, Gent, ... and any volumetric law).
        prony: Relative moduli and relaxation times of the isochoric part.
        time_scale: Physical time per unit of the problem's time (> 0; 1: the
            problem's time is the physical time).
        quadrature_degree: Degree of the volume rule; default the problem's.
        name: Prefix of the history fields' names (and of the checkpoint entries).

    Attributes:
        invertible: ``False``.
        history: The :class:`ViscousHistory` (the updater).
        Q: The fields of :math:`Q_i^n` (``None`` until bound).
        S_previous: The field of :math:`S_\text{iso}^n` (``None`` until bound).
    """

    invertible = False
    state_hooks: tuple = ()
    """No state hooks: the history moves once a step, through :attr:`updaters`."""

    def __init__(
        self,
        elastic: SplitEnergy,
        prony: PronySeries,
        *,
        time_scale: float = 1.0,
        quadrature_degree: int | None = None,
        name: str = "viscoelastic",
    ):
        where = "Viscoelastic"
        from hyperfem.problem.mixed import SplitEnergy

        if not isinstance(elastic, SplitEnergy):
            raise ParameterError(
                f"{where}: elastic must be a SplitEnergy (isochoric part, bulk modulus, volumetric law), "
                f"got {type(elastic).__name__}"
            )
        if not isinstance(prony, PronySeries):
            raise ParameterError(f"{where}: prony must be a PronySeries, got {type(prony).__name__}")
        check_positive("time_scale", time_scale, where)
        if quadrature_degree is not None and not (
            isinstance(quadrature_degree, int) and not isinstance(quadrature_degree, bool) and quadrature_degree >= 1
        ):
            raise ParameterError(
                f"{where}: quadrature_degree must be an integer >= 1 or None, got {quadrature_degree!r}"
            )
        if not (isinstance(name, str) and name.isidentifier()):
            raise ParameterError(f"{where}: name must be an identifier (letters, digits, _), got {name!r}")
        self.elastic = elastic
        self.prony = prony
        self.time_scale = float(time_scale)
        self.quadrature_degree = quadrature_degree
        self.name = name
        self.history = ViscousHistory(self)
        self.Q: list[QuadratureField] | None = None
        self.S_previous: QuadratureField | None = None
        self.F: Expr | None = None
        self._S_expression: fem.Expression | None = None
        self._functions: list[fem.Function] = []
        self._comm: MPI.Comm = MPI.COMM_WORLD
        self._c: list[fem.Constant] = []
        self._d: list[fem.Constant] = []
        self._gamma: fem.Constant

    # -- EnergyProtocol -------------------------------------------------------------------
    @property
    def updaters(self) -> tuple[ViscousHistory]:
        """The updaters a problem calls from ``set_time``: ``(history,)``."""
        return (self.history,)

    @property
    def quadrature_rule_degree(self) -> int | None:
        """Degree of the volume rule the history sits on (``None`` until bound)."""
        return None if self.S_previous is None else self.S_previous.degree

    def tangent_correction(self, F: Expr) -> None:
        """None: the history is frozen over the step, the stress is the derivative of the energy."""
        return None

    def bind(self, F: Expr, quadrature_degree: int | None = None) -> None:
        """Attach the history fields to ``F`` (the problem's) on the rule of ``quadrature_degree``.

        Binding again to the same ``F`` and degree is a no-op.

        Raises:
            ParameterError: ``F`` is symbolic, not 2×2/3×3, or not the ``F`` (or degree) bound before.
        """
        where = "Viscoelastic"
        if isinstance(F, ufl.classes.Variable):  # ufl.variable(F), as stress() builds it: F itself
            F = F.ufl_operands[0]
        if quadrature_degree is not None and self.quadrature_degree not in (None, quadrature_degree):
            raise ParameterError(
                f"{where}: built for quadrature degree {self.quadrature_degree}, "
                f"the problem integrates with degree {quadrature_degree}"
            )
        degree = quadrature_degree if quadrature_degree is not None else self.quadrature_degree
        if self.F is not None:
            if not F == self.F:
                raise ParameterError(
                    f"{where}: already bound to the deformation gradient of another problem; "
                    "create one material object per problem"
                )
            if degree is not None and self.S_previous is not None and degree != self.S_previous.degree:
                raise ParameterError(
                    f"{where}: bound on quadrature degree {self.S_previous.degree}, asked for {degree}"
                )
            return
        shape = F.ufl_shape
        if len(shape) != 2 or shape[0] != shape[1] or shape[0] not in (2, 3):
            raise ParameterError(f"{where}: F must be a 2x2 or 3x3 tensor, got shape {shape}")
        from ufl.algorithms import extract_coefficients

        functions = [c for c in extract_coefficients(F) if isinstance(c, fem.Function)]
        if not functions:
            raise ParameterError(
                f"{where}: needs the deformation gradient of a DOLFINx Function (a problem's F = I + grad u), "
                "got a symbolic F"
            )
        mesh = functions[0].function_space.mesh
        if degree is None:
            from hyperfem.problem.quadrature import volume_quadrature_degree

            p = functions[0].function_space.ufl_element().embedded_superdegree
            degree = volume_quadrature_degree(p, mesh.topology.cell_type)
        d = shape[0]
        self._functions = functions
        self._comm = mesh.comm
        self.Q = [QuadratureField(mesh, degree, (d, d), name=f"{self.name}_Q{i}") for i in range(self.prony.terms)]
        self.S_previous = QuadratureField(mesh, degree, (d, d), name=f"{self.name}_S")
        self._c = [fem.Constant(mesh, 1.0) for _ in range(self.prony.terms)]
        self._d = [fem.Constant(mesh, gi) for gi in self.prony.g]
        self._gamma = fem.Constant(mesh, 1.0)
        self._S_expression = self.S_previous.expression(isochoric_pk2(self.elastic.isochoric, F))
        self.F = F

    # -- the energy -----------------------------------------------------------------------
    def frozen_stress(self) -> Expr:
        r"""The frozen part :math:`B_n = \sum_i (c_i Q_i^n - g_i a_i S_\text{iso}^n)` of :math:`S^{n+1}`."""
        if self.Q is None or self.S_previous is None:
            raise ParameterError("Viscoelastic: not bound to a deformation gradient yet (call it with F first)")
        S_n = self.S_previous.function
        return sum((c * Q.function - d * S_n for c, d, Q in zip(self._c, self._d, self.Q, strict=True)), 0 * S_n)

    def __call__(self, F: Expr) -> Expr:
        self.bind(F)
        C = F.T * F
        return (
            self.elastic.volumetric_energy(ufl.det(F))
            + self._gamma * self.elastic.isochoric(F)
            + 0.5 * ufl.inner(self.frozen_stress(), C)
        )

    def stress(self, F: Expr) -> Expr:
        r"""First Piola–Kirchhoff stress :math:`P = \partial\Pi/\partial F = F S^{n+1}` with the history frozen.

        At an accepted state it is the stress of the model at that time
        (the recursion's :math:`S^{n+1}`, pushed forward by :math:`F`).
        """
        Fv = ufl.variable(F)
        return ufl.diff(self(Fv), Fv)

    def energy(self, F: Expr) -> Expr:
        r"""The incremental potential :math:`\Pi(F)` (``self(F)``; as :meth:`SplitEnergy.energy
        <hyperfem.problem.SplitEnergy.energy>` of the elastic law, with the history)."""
        return self(F)

    def mixed_energy(self, F: Expr, p: Expr, theta: Expr) -> Expr:
        r"""Three-field density :math:`U(\theta) + \gamma\psi_\text{iso}(F) + \tfrac12 B_n : F^TF + p(\det F - \theta)`.

        As :meth:`SplitEnergy.mixed_energy <hyperfem.problem.SplitEnergy.mixed_energy>` with the
        isochoric part of the step: the isochoric stress relaxes, the volumetric
        energy is that of the volume field :math:`\theta`. ``F`` must be the
        deformation gradient the material is bound to (the problem binds it).
        """
        self.bind(F)
        C = F.T * F
        return (
            self.elastic.volumetric_energy(theta)
            + self._gamma * self.elastic.isochoric(F)
            + 0.5 * ufl.inner(self.frozen_stress(), C)
            + p * (ufl.det(F) - theta)
        )

    def long_term_energy(self, F: Expr) -> Expr:
        r"""The relaxed law :math:`U(J) + g_\infty\,\psi_\text{iso}(F)` (the limit of a long hold)."""
        return self.elastic.volumetric_energy(ufl.det(F)) + self.prony.g_inf * self.elastic.isochoric(F)
