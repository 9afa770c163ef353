r"""Contact forces under generalized-:math:`\alpha`: interpolated between the step's ends, as the internal forces.

A generalized-:math:`\alpha` step (:class:`~hyperfem.dynamics.GeneralizedAlpha`)
balances the inertia at :math:`t_{n+1-\alpha_m}` against the internal and
external forces at :math:`t_{n+1-\alpha_f}`: the incremental potential holds
:math:`\Pi(u_\alpha)/(1-\alpha_f)`, :math:`u_\alpha = (1-\alpha_f)u_{n+1} + \alpha_f u_n`
(:mod:`~hyperfem.dynamics.incremental`), whose derivative is
:math:`f_\text{int}(u_\alpha)`. A contact term :math:`E(u_{n+1})` added as it
stands would balance the contact force at :math:`u_{n+1}` against the internal
forces at :math:`u_\alpha`: an offset of about :math:`\alpha_f` times one step's
change of the contact force. Measured on a light block pushed by a plane
(``tests/test_contact_dynamics.py``, :math:`\rho_\infty = 0.8`, from :math:`2\hat d`
below it; ``benchmarks/contact_alpha.py``): the final force 2.4 % below the
quasi-static one at :math:`\Delta t = 0.05`, 4.9 % at :math:`\Delta t = 0.1`.

The contact force (barrier and friction) is therefore interpolated between the
ends of the step (Erlicher, Bonaventura and Bursi 2002, the force-interpolated
generalized-:math:`\alpha`):

.. math::
    f_{c,\alpha} = (1-\alpha_f)\,f_c(u_{n+1}) + \alpha_f\,f_c(u_n),

the second term frozen at the step's start state :math:`u_n` (the obstacle
where it was at :math:`t_n`, the friction with the lag it had when that state
was accepted). It is the gradient of the energy term

.. math::
    E_\alpha(u) = (1-\alpha_f)\,E(u) + \alpha_f\,f_c(u_n)\cdot(u - u_n),

so the energy line search, the collision filter (the barrier still keeps
:math:`u_{n+1}` off the obstacle placed at :math:`t_{n+1}`) and the tangent
(:math:`(1-\alpha_f)\nabla^2 E`, still positive semi-definite) work as before.
For a linear force it is exactly the force at :math:`u_\alpha`; in general both
interpolations agree to second order in the step, and an equilibrium kept at
:math:`t_n` is kept at :math:`t_{n+1}` to second order: the offsets above become
-0.03 % and -0.31 % (Newmark, which does not damp the
ringing of the push, is 0.6 % and 0.9 % below it). What is left is the ringing of the scheme itself: in the
limit of a light body the defect of a state decays by :math:`-\alpha_f/(1-\alpha_f)
= -\rho_\infty` per step, for the contact now as for the elastic forces (a body
that starts inside the barrier's reach, out of balance, ends 0.3–0.6 % off).

:class:`ForceInterpolation` is what a contact's barrier holds (and a tie,
:mod:`~hyperfem.contact.tie`, whose linear force it interpolates exactly): the problem
tells it (``force_interpolation()``,
:meth:`~hyperfem.dynamics.IncrementalProblem.force_interpolation`) whether a
generalized-:math:`\alpha` step is being solved; outside one (quasi-static,
Newmark, backward Euler, between steps: outputs, reactions, the initial
acceleration) the contact's energy, gradient and Hessian are its own.
:math:`f_c(u_n)` is taken once per step start (keyed by :math:`t_n` and
:math:`u_n`, so a step retried after a cut-back reuses it), summed into one
value per dof.

**Restart.** The frozen friction force is that of the lag of the step that
reached :math:`u_n`; a restart takes the lag again *at* :math:`u_n` (for the
next step, :meth:`~hyperfem.solver.external.ExternalTerms.remember`), not
the one before it, so :math:`f_c(u_n)` cannot be taken again from the
restart state. A checkpoint therefore holds it (:meth:`ForceInterpolation.state_functions`,
a function of the unknown's space, taken at the accepted state and kept for
the next step; :mod:`hyperfem.simulation.checkpoint`), and the restarted
run's first step uses it (:meth:`ForceInterpolation.restart`): a restarted
generalized-:math:`\alpha` run with friction equals the uninterrupted one
(``tests/test_contact_restart.py``: to 1e-10, 1 and 2 ranks; before, its
first step after the restart had the force 3 % and the friction force
100 % off).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from hyperfem.contact.obstacles import obstacle_time

__all__ = ["ForceInterpolation"]

FrozenGradient = Callable[[np.ndarray, float], tuple[np.ndarray, np.ndarray]]
"""``(u_n, t_n) -> (dofs, values)``: a contact's own gradient at ``u_n`` with its obstacle placed at ``t_n``."""


class ForceInterpolation:
    r"""The generalized-:math:`\alpha` weights of one contact's energy (module docstring).

    Args:
        problem: The problem the contact is bound to (an
            :class:`~hyperfem.dynamics.IncrementalProblem` or any other: without
            ``force_interpolation()`` nothing is interpolated).
        frozen_gradient: The contact's gradient (barrier and friction) at a state with its obstacle placed at a time
            (``(u, t) -> (dofs, values)``), leaving the contact placed where it was.
        comm: The communicator when ``frozen_gradient`` is collective (mesh contact: the surface is gathered), so
            every rank decides alike whether to take it; ``None`` for per-rank contacts.
    """

    def __init__(self, problem: object, frozen_gradient: FrozenGradient, comm: MPI.Comm | None = None):
        self._problem = problem
        self._state = getattr(problem, "force_interpolation", None)
        self._frozen_gradient = frozen_gradient
        self._comm = comm
        self._key: float | None = None
        self._u_n: np.ndarray | None = None
        self._dofs: np.ndarray = np.zeros(0, dtype=np.int32)
        self._values: np.ndarray = np.zeros(0)
        self._function: fem.Function | None = None

    @property
    def interpolates(self) -> bool:
        r"""Whether the problem's steps are generalized-:math:`\alpha` steps with :math:`\alpha_f > 0`."""
        alpha_f = getattr(getattr(self._problem, "integrator", None), "alpha_f", 0.0)
        return self._state is not None and bool(alpha_f)

    def _take(self, u_n: np.ndarray, t_n: float, check_state: bool) -> None:
        r"""Take :math:`f_c(u_n)` with the obstacle at ``t_n`` unless it is the one held (summed per dof)."""
        same = self._key == t_n
        if same and check_state:
            assert self._u_n is not None  # set with the key
            same = bool(np.array_equal(self._u_n, u_n))
            if self._comm is not None:
                same = bool(self._comm.allreduce(same, op=MPI.LAND))
        if same:
            return
        dofs, values = self._frozen_gradient(u_n, t_n)
        # One value per dof: what a checkpoint holds (state_functions), so a restarted run adds the same numbers.
        dense = np.zeros(len(u_n))
        np.add.at(dense, np.asarray(dofs).ravel(), np.asarray(values, dtype=float).ravel())
        self._dofs = np.flatnonzero(dense)
        self._values = dense[self._dofs]
        self._key, self._u_n = t_n, u_n.copy()

    def _current(self, check_state: bool = False) -> tuple[float, np.ndarray] | None:
        r""":math:`(\alpha_f, u_n)` of the step being solved (taking :math:`f_c(u_n)` if it is new), or ``None``."""
        state = None if self._state is None else self._state()
        if state is None:
            return None
        af, u_n, t_loads = state
        self._take(u_n, obstacle_time(self._problem, t_loads), check_state)  # the obstacle where it was at t_n
        return float(af), u_n

    def begin(self) -> None:
        r"""At a contact's ``update(t)``, before it moves its obstacle or its friction lag: take :math:`f_c(u_n)` at the
        start of a new step (collective where the contact is)."""
        self._current(check_state=True)

    def state_functions(self) -> dict[str, fem.Function]:
        r"""What a checkpoint holds: :math:`f_c(u_n)` at the accepted state now in the unknown (collective).

        Taken as the next step will take it (with the friction's lag in use, before the next ``update(t)`` moves
        it) and kept for that step; empty where nothing is interpolated (module docstring).
        """
        if not self.interpolates:
            return {}
        problem: Any = self._problem
        if self._function is None:
            self._function = fem.Function(problem.u.function_space, name="frozen_contact_force")
        u_n = problem.u.x.array
        self._take(u_n, obstacle_time(problem, problem.time), check_state=True)
        self._function.x.array[:] = 0.0
        self._function.x.array[self._dofs] = self._values
        return {"frozen_force": self._function}

    def restart(self, t: float) -> None:
        r"""The checkpoint's :math:`f_c(u_n)` was read into :meth:`state_functions`: hold it for the state now in
        the unknown, accepted at the load time ``t`` (this rank's owned dofs)."""
        if self._function is None:
            return
        problem: Any = self._problem
        index_map = self._function.function_space.dofmap.index_map
        owned = self._function.x.array[: index_map.size_local * self._function.function_space.dofmap.index_map_bs]
        self._dofs = np.flatnonzero(owned)
        self._values = owned[self._dofs].copy()
        self._key, self._u_n = obstacle_time(problem, t), problem.u.x.array.copy()

    @property
    def weight(self) -> float:
        r""":math:`1 - \alpha_f` during a generalized-:math:`\alpha` step, else 1 (the Hessian's factor)."""
        current = self._current()
        return 1.0 if current is None else 1.0 - current[0]

    def energy(self, own: float, u: np.ndarray) -> float:
        r""":math:`(1-\alpha_f)E(u) + \alpha_f f_c(u_n)\cdot(u - u_n)` of this rank, from its :math:`E(u)` ``own``."""
        current = self._current()
        if current is None:
            return own
        af, u_n = current
        linear = float((self._values * (u[self._dofs] - u_n[self._dofs])).sum()) if self._dofs.size else 0.0
        return (1.0 - af) * own + af * linear

    def gradient(self, dofs: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`(1-\alpha_f)\nabla E(u) + \alpha_f f_c(u_n)` from the contact's own ``(dofs, values)``.

        During a step the entries come one dof a row, shape ``(m, 1)``.
        """
        current = self._current()
        if current is None:
            return dofs, values
        af = current[0]
        if not self._dofs.size:
            return dofs, (1.0 - af) * values
        dofs = np.concatenate([np.asarray(dofs).ravel(), self._dofs])
        return dofs[:, None], np.concatenate([(1.0 - af) * np.asarray(values).ravel(), af * self._values])[:, None]
