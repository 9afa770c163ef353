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

:class:`ForceInterpolation` is what a contact's barrier holds: the problem
tells it (``force_interpolation()``,
:meth:`~hyperfem.dynamics.IncrementalProblem.force_interpolation`) whether a
generalized-:math:`\alpha` step is being solved; outside one (quasi-static,
Newmark, backward Euler, between steps: outputs, reactions, the initial
acceleration) the contact's energy, gradient and Hessian are its own.
:math:`f_c(u_n)` is taken once per step start (keyed by :math:`t_n` and
:math:`u_n`, so a step retried after a cut-back reuses it). After a restart the
frozen friction force of the restart state is zero for the first step (the
lag of the step that reached it is not in the checkpoint).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
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

    def _current(self, check_state: bool = False) -> tuple[float, np.ndarray] | None:
        r""":math:`(\alpha_f, u_n)` of the step being solved (taking :math:`f_c(u_n)` if it is new), or ``None``."""
        state = None if self._state is None else self._state()
        if state is None:
            return None
        af, u_n, t_loads = state
        t_n = obstacle_time(self._problem, t_loads)  # where the obstacle was when u_n was accepted
        same = self._key == t_n
        if same and check_state:
            assert self._u_n is not None  # set with the key
            same = bool(np.array_equal(self._u_n, u_n))
            if self._comm is not None:
                same = bool(self._comm.allreduce(same, op=MPI.LAND))
        if not same:
            dofs, values = self._frozen_gradient(u_n, t_n)
            self._dofs, self._values = np.asarray(dofs), np.asarray(values, dtype=float)
            self._key, self._u_n = t_n, u_n.copy()
        return float(af), u_n

    def begin(self) -> None:
        r"""At a contact's ``update(t)``, before it moves its obstacle or its friction lag: take :math:`f_c(u_n)` at the
        start of a new step (collective where the contact is)."""
        self._current(check_state=True)

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
        r""":math:`(1-\alpha_f)\nabla E(u) + \alpha_f f_c(u_n)` from the contact's own ``(dofs, values)``."""
        current = self._current()
        if current is None:
            return dofs, values
        af = current[0]
        if not self._dofs.size:
            return dofs, (1.0 - af) * values
        return np.concatenate([dofs, self._dofs]), np.concatenate([(1.0 - af) * values, af * self._values])
