r"""Frictionless contact of a body with a rigid plane: the IPC barrier of its boundary nodes.

:class:`PlaneContact` names the boundary that may touch and the obstacle (a
:class:`~hyperfem.contact.obstacles.HalfSpace` with an optional prescribed
translation and rotation); :meth:`PlaneContact.bind` gives the :class:`PlaneBarrier` of a
problem, the term

.. math::
    \kappa B(u) = \kappa \sum_a b\bigl(d_a(u)\bigr), \qquad
    d_a(u) = (X_a + u_a - p(t))\cdot n(t),

over the contact nodes :math:`a` (:mod:`~hyperfem.contact.nodes`), with the
IPC barrier :math:`b` of width :math:`\hat d` (:mod:`~hyperfem.contact.barrier`)
and stiffness :math:`\kappa` (defaults in :mod:`~hyperfem.contact.defaults`).
Its derivatives are per node,

.. math::
    \frac{\partial\,\kappa B}{\partial u_a} = \kappa\,b'(d_a)\,n, \qquad
    \frac{\partial^2 \kappa B}{\partial u_a^2} = \kappa\,b''(d_a)\,n\,n^T,

so the Hessian is one :math:`3\times3` block per active node
(:math:`d_a < \hat d`), positive semi-definite without projection
(:math:`b'' > 0` on :math:`(0, \hat d)`), and inside the finite-element
sparsity pattern (a node's own block). The barrier is an
:class:`~hyperfem.solver.external.ExternalEnergy` of
:class:`~hyperfem.solver.NewtonSolver` (``external_energies=[...]``): it
enters the energy line search, the residual and the tangent, and brings its
collision-free step filter (:class:`~hyperfem.contact.ccd.PlaneCollisionFilter`).

MPI: each rank evaluates the nodes it owns; no gathering is needed for a
plane, only the ``allreduce`` of the energy and of the outputs.

Example::

    contact = hf.contact.PlaneContact("bottom", point=(0, 0, 0), normal=(0, 0, 1)).bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[contact])
    outputs = [Recorder(contact)]   # contact_force, contact_active, contact_min_distance per step
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hyperfem.contact.ccd import CCD_SAFETY, PlaneCollisionFilter
from hyperfem.contact.defaults import default_dhat, default_stiffness
from hyperfem.contact.nodal import NodalBarrier
from hyperfem.contact.nodes import boundary_nodes
from hyperfem.contact.settings import check_contact_settings, check_dhat_fits
from hyperfem.contact.obstacles import HalfSpace, Motion, check_plane, check_rotation
from hyperfem.errors import ParameterError
from hyperfem.loading.motion import RigidRotation
from hyperfem.loading.profiles import linear_profile
from hyperfem.problem.protocol import SolidProblem
from hyperfem.validation import check_name

__all__ = ["PlaneBarrier", "PlaneContact"]


@dataclass(frozen=True)
class PlaneContact:
    r"""Intersection-free contact (optional friction) of a boundary with a rigid plane (module docstring).

    Attributes:
        boundary: The boundary group whose nodes may touch the plane.
        point: A point of the plane (where the translation is 0).
        normal: The plane's outward normal, pointing to the body's side.
        dhat: Barrier width :math:`\hat d > 0` (``None``: :func:`~hyperfem.contact.defaults.default_dhat`).
        stiffness: Barrier stiffness :math:`\kappa > 0` (``None``:
            :func:`~hyperfem.contact.defaults.default_stiffness`; fixed for the run).
        motion: A translation of the plane, scaled by ``profile(t)`` (``None``: it stays), or a path ``t -> s(t)``
            (e.g. :class:`~hyperfem.loading.Waypoints`: pressed in, then dragged; ``profile`` is then unused).
        profile: :math:`f(t)` of the translation (default: the load factor).
        safety: The collision filter's :math:`s \in (0, 1)` (:data:`~hyperfem.contact.ccd.CCD_SAFETY`).
        name: Prefix of the output columns (``contact_force``, ...).
        friction: Coulomb coefficient :math:`\mu \ge 0` (0: frictionless), smoothed and lagged per
            step as in IPC (:mod:`~hyperfem.contact.nodal`).
        friction_epsilon: The slip length :math:`\epsilon > 0` below which a node sticks elastically
            (``None``: :math:`0.1\,\hat d`).
        rotation: A :class:`~hyperfem.loading.RigidRotation` of the plane (3D), composed with the translation:
            the normal turns, :math:`n(t) = R(t)\,n_0`, the point about the pivot
            (:mod:`~hyperfem.contact.obstacles`; ``None``: it does not turn).

    Raises:
        ParameterError: A bad entry (one line), or ``ipctk`` is not installed
            (the message names the extra ``hyperfem[contact]``).
    """

    boundary: str
    point: Sequence[float]
    normal: Sequence[float]
    dhat: float | None = None
    stiffness: float | None = None
    motion: Motion = None
    profile: Callable[[float], float] = linear_profile
    safety: float = CCD_SAFETY
    name: str = "contact"
    friction: float = 0.0
    friction_epsilon: float | None = None
    rotation: RigidRotation | None = None

    def __post_init__(self) -> None:
        check_name(self.boundary, "boundary", "PlaneContact")
        where = f"PlaneContact on {self.boundary!r}"
        p, n, m = check_plane(self.point, self.normal, self.motion, where)
        check_rotation(self.rotation, len(p), where)
        object.__setattr__(self, "point", p)
        object.__setattr__(self, "normal", n)
        object.__setattr__(self, "motion", m)
        check_contact_settings(
            where, dhat=self.dhat, stiffness=self.stiffness, safety=self.safety, friction=self.friction,
            friction_epsilon=self.friction_epsilon, profile=self.profile, name=self.name,
        )

    @property
    def obstacle(self) -> HalfSpace:
        """The plane as a :class:`~hyperfem.contact.obstacles.HalfSpace`."""
        return HalfSpace(self.point, self.normal, self.motion, self.profile, self.rotation)

    def bind(self, problem: SolidProblem) -> PlaneBarrier:
        """The barrier of this contact on ``problem`` (collective).

        Raises:
            UnknownGroupError: ``boundary`` is not a boundary group of the mesh (the message lists them).
            ParameterError: The plane's dimension differs from the mesh's, or a
                node starts on or behind the plane (the message gives the node and its distance).
        """
        return PlaneBarrier(self, problem)


class PlaneBarrier(NodalBarrier):
    r"""The barrier term :math:`\kappa B(u)` of a :class:`PlaneContact` on a problem (module docstring).

    An :class:`~hyperfem.solver.external.ExternalEnergy`. Its outputs
    (:meth:`record`, for :class:`~hyperfem.simulation.Recorder`) are the force
    the plane exerts on the body, :math:`f = -\sum_a \kappa b'(d_a)\,n`, the
    number of active nodes (:math:`d_a < \hat d`) and the smallest distance.

    Args:
        contact: The contact.
        problem: The problem.

    Attributes:
        dhat: :math:`\hat d`.
        stiffness: :math:`\kappa`.
        nodes: The owned contact nodes.
        step_filter: The collision filter.
        time: The time (load factor) the plane is at.
    """

    behind = "on or behind the plane"
    side_hint = "; the normal points to the body's side"

    def __init__(self, contact: PlaneContact, problem: SolidProblem):
        self.contact = contact
        self.where = f"PlaneContact on {contact.boundary!r}"
        self.problem = problem
        self.comm = problem.domain.comm
        self.obstacle = contact.obstacle
        if self.obstacle.dim != problem.domain.gdim:
            raise ParameterError(
                f"{self.where}: the plane has {self.obstacle.dim} components, the mesh {problem.domain.gdim}"
            )
        self.normal = self.obstacle.unit_normal
        self.nodes = boundary_nodes(problem, contact.boundary)
        self.dhat = contact.dhat if contact.dhat is not None else default_dhat(problem, contact.boundary)
        check_dhat_fits(problem, self.dhat, self.where)
        self.update(problem.time)
        self._check_start("plane")
        self.stiffness = (
            contact.stiffness if contact.stiffness is not None else default_stiffness(problem, self.nodes, self.normal)
        )
        self._init_friction(contact)
        self.step_filter = PlaneCollisionFilter(self.nodes.dofs, self.distances, self.normal, contact.safety)

    # -- the ExternalEnergy contract ----------------------------------------
    def _place(self, time: float) -> None:
        """Put (and turn) the plane where it is at the obstacle time ``time``: its point and normal."""
        self.time = float(time)
        self._origin = self.obstacle.origin(self.time)
        if self.obstacle.rotation is not None:
            self.normal = self.obstacle.normal_at(self.time)
            if hasattr(self, "step_filter"):
                self.step_filter.normal = self.normal

    def distances(self, u: np.ndarray) -> np.ndarray:
        """Signed distances :math:`d_a` of the owned nodes for the unknown's local array ``u``."""
        return (self.nodes.positions(u) - self._origin) @ self.normal

    def _barrier_gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`\kappa b'(d_a)\,n` at the active nodes: ``(dofs, values)`` of shape ``(m, dim)``."""
        rows, first, _ = self._active(u)
        return self.nodes.dofs[rows], self.stiffness * first[:, None] * self.normal[None, :]

    def _barrier_hessian(self, u: np.ndarray, project: bool = True) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`\kappa b''(d_a)\,n n^T` at the active nodes: ``(dofs, blocks)``, blocks ``(m, dim, dim)``."""
        rows, _, second = self._active(u)
        outer = np.outer(self.normal, self.normal)
        return self.nodes.dofs[rows], self.stiffness * second[:, None, None] * outer[None, :, :]

    def normals(self, u: np.ndarray) -> np.ndarray:
        """The plane's unit normal at every owned node."""
        return np.tile(self.normal, (len(self.nodes.dofs), 1))
