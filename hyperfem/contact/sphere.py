r"""Frictionless contact of a body with a rigid sphere (an indenter, a spherical tool): the IPC barrier of its nodes.

:class:`SphereContact` names the boundary that may touch and the ball
(:class:`~hyperfem.contact.obstacles.Ball`: centre, radius, an optional
prescribed translation and rotation); :meth:`SphereContact.bind` gives the
:class:`SphereBarrier` of a problem, the term

.. math::
    \kappa B(u) = \kappa \sum_a b\bigl(d_a(u)\bigr), \qquad
    d_a(u) = |x_a - c(t)| - R, \quad x_a = X_a + u_a,

over the contact nodes :math:`a`, with the IPC barrier :math:`b` of width
:math:`\hat d` (:mod:`~hyperfem.contact.barrier`). With :math:`r_a = |x_a - c|`
and the outward unit vector :math:`n_a = (x_a - c)/r_a`,

.. math::
    \nabla d_a = n_a, \qquad \nabla^2 d_a = \frac{I - n_a n_a^T}{r_a}, \qquad
    \frac{\partial^2 \kappa B}{\partial u_a^2} = \kappa\Bigl(b''(d_a)\,n_a n_a^T
      + b'(d_a)\,\frac{I - n_a n_a^T}{r_a}\Bigr).

The second part is negative semi-definite (:math:`b' < 0`): the exact block
is indefinite. While the nodes still move the tangent gets its projection
onto the positive semi-definite cone (eigenvalues clipped at 0,
``numpy.linalg.eigh`` on the stack of :math:`3\times3` blocks), as in IPC;
once no node moved by :data:`~hyperfem.contact.nodal.SETTLED_MOVE`
:math:`\hat d` since the last tangent it gets the exact blocks, so Newton
ends at its quadratic rate (always projected it converged linearly, at a
rate of 0.41 for a ball dragged across a slab;
:meth:`~hyperfem.contact.nodal.NodalBarrier.hessian`). The energy and
gradient are exact either way. The blocks lie in the finite-element
sparsity pattern (a node's own block), and the collision filter is the exact
point–ball CCD (:class:`~hyperfem.contact.ccd.SphereCollisionFilter`).

MPI: each rank evaluates the nodes it owns (no gathering), as for the plane.

Example::

    tool = hf.contact.SphereContact("top", center=(0.5, 0.5, 1.3), radius=0.3, motion=(0, 0, -0.1)).bind(problem)
    solver = hf.NewtonSolver(problem, external_energies=[tool])
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from hyperfem.contact.ccd import CCD_SAFETY, SphereCollisionFilter
from hyperfem.contact.defaults import default_dhat, default_stiffness
from hyperfem.contact.nodal import NodalBarrier
from hyperfem.contact.nodes import boundary_nodes
from hyperfem.contact.settings import check_contact_settings, check_dhat_fits
from hyperfem.contact.obstacles import Ball, Motion, check_ball, check_rotation
from hyperfem.errors import ParameterError
from hyperfem.loading.motion import RigidRotation
from hyperfem.loading.profiles import linear_profile
from hyperfem.problem.protocol import SolidProblem
from hyperfem.validation import check_name

__all__ = ["SphereBarrier", "SphereContact", "project_psd"]


def project_psd(blocks: np.ndarray) -> np.ndarray:
    """The nearest positive semi-definite matrices of a stack of symmetric blocks (eigenvalues clipped at 0)."""
    if not len(blocks):
        return blocks
    values, vectors = np.linalg.eigh(blocks)
    return np.einsum("mij,mj,mkj->mik", vectors, np.maximum(values, 0.0), vectors)


@dataclass(frozen=True)
class SphereContact:
    r"""Intersection-free contact (optional friction) of a boundary with a rigid sphere (module docstring).

    Attributes:
        boundary: The boundary group whose nodes may touch the sphere.
        center: The sphere's centre (where the translation is 0).
        radius: Its radius :math:`R > 0`.
        dhat: Barrier width :math:`\hat d > 0` (``None``: :func:`~hyperfem.contact.defaults.default_dhat`).
        stiffness: Barrier stiffness :math:`\kappa > 0` (``None``: the mean tangent diagonal at the contact
            nodes, :func:`~hyperfem.contact.defaults.default_stiffness`; fixed for the run).
        motion: A translation of the sphere, scaled by ``profile(t)`` (``None``: it stays), or a path ``t -> s(t)``
            (e.g. :class:`~hyperfem.loading.Waypoints`: pressed in, then dragged; ``profile`` is then unused).
        profile: :math:`f(t)` of the translation (default: the load factor).
        safety: The collision filter's :math:`s \in (0, 1)` (:data:`~hyperfem.contact.ccd.CCD_SAFETY`).
        name: Prefix of the output columns (``contact_force``, ...).
        friction: Coulomb coefficient :math:`\mu \ge 0` (0: frictionless), smoothed and lagged per
            step as in IPC (:mod:`~hyperfem.contact.nodal`).
        friction_epsilon: The slip length :math:`\epsilon > 0` below which a node sticks elastically
            (``None``: :math:`0.1\,\hat d`).
        rotation: A :class:`~hyperfem.loading.RigidRotation` of the ball, composed with the translation
            (:mod:`~hyperfem.contact.obstacles`; ``None``: it does not turn). About its own centre it changes
            nothing but the friction's slip, which is taken relative to the ball's surface.

    Raises:
        ParameterError: A bad entry (one line), or ``ipctk`` is not installed
            (the message names the extra ``hyperfem[contact]``).
    """

    boundary: str
    center: Sequence[float]
    radius: float
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
        check_name(self.boundary, "boundary", "SphereContact")
        where = f"SphereContact on {self.boundary!r}"
        c, r, m = check_ball(self.center, self.radius, self.motion, where)
        check_rotation(self.rotation, len(c), where)
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "motion", m)
        check_contact_settings(
            where, dhat=self.dhat, stiffness=self.stiffness, safety=self.safety, friction=self.friction,
            friction_epsilon=self.friction_epsilon, profile=self.profile, name=self.name,
        )

    @property
    def obstacle(self) -> Ball:
        """The sphere as a :class:`~hyperfem.contact.obstacles.Ball`."""
        return Ball(self.center, self.radius, self.motion, self.profile, self.rotation)

    def bind(self, problem: SolidProblem) -> SphereBarrier:
        """The barrier of this contact on ``problem`` (collective).

        Raises:
            UnknownGroupError: ``boundary`` is not a boundary group of the mesh (the message lists them).
            ParameterError: The centre's dimension differs from the mesh's, or a
                node starts on or inside the sphere (the message gives the node and its distance).
        """
        return SphereBarrier(self, problem)


class SphereBarrier(NodalBarrier):
    r"""The barrier term :math:`\kappa B(u)` of a :class:`SphereContact` on a problem (module docstring).

    An :class:`~hyperfem.solver.external.ExternalEnergy`; its outputs are those
    of :class:`~hyperfem.contact.nodal.NodalBarrier` (the force the sphere
    exerts, :math:`-\sum_a \kappa b'(d_a)\,n_a`, the active nodes, the smallest distance).

    Args:
        contact: The contact.
        problem: The problem.

    Attributes:
        dhat: :math:`\hat d`.
        stiffness: :math:`\kappa`.
        nodes: The owned contact nodes.
        step_filter: The collision filter.
        time: The time (load factor) the sphere is at.
    """

    behind = "on or inside the sphere"
    shape = "sphere"
    curved = True
    projector: np.ndarray | None = None
    """Offsets and steps are projected with it (a cylinder's :math:`I - a a^T`; ``None``: a ball)."""

    def __init__(self, contact: SphereContact, problem: SolidProblem):
        self.contact = contact
        self.where = f"{type(contact).__name__} on {contact.boundary!r}"
        self.problem = problem
        self.comm = problem.domain.comm
        self.obstacle = contact.obstacle
        gdim = problem.domain.gdim
        if self.obstacle.dim != gdim:
            raise ParameterError(f"{self.where}: the {self.shape} has {self.obstacle.dim} components, the mesh {gdim}")
        self.radius = float(contact.radius)
        self.nodes = boundary_nodes(problem, contact.boundary)
        self.dhat = contact.dhat if contact.dhat is not None else default_dhat(problem, contact.boundary)
        check_dhat_fits(problem, self.dhat, self.where)
        self.update(problem.time)
        self._check_start(self.shape)
        mean = np.full(gdim, 1.0 / np.sqrt(gdim))  # n^T K n averaged over the directions: the mean diagonal
        self.stiffness = (
            contact.stiffness if contact.stiffness is not None else default_stiffness(problem, self.nodes, mean)
        )
        self._init_friction(contact)
        self.step_filter = SphereCollisionFilter(
            self.nodes.dofs, self.nodes.X, lambda: self._center, self.radius, contact.safety, self.projector
        )

    # -- the ExternalEnergy contract ----------------------------------------
    def _place(self, time: float) -> None:
        """Put the sphere where it is at the obstacle time ``time``."""
        self.time = float(time)
        self._center = self.obstacle.origin(self.time)

    def _offsets(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:math:`q_a = x_a - c` (projected with :attr:`projector`, if any) and :math:`r_a = |q_a|`, owned nodes."""
        q = self.nodes.positions(u) - self._center
        if self.projector is not None:
            q = q @ self.projector
        return q, np.linalg.norm(q, axis=1)

    def distances(self, u: np.ndarray) -> np.ndarray:
        """Signed distances :math:`d_a = |x_a - c| - R` of the owned nodes for the unknown's local array ``u``."""
        return self._offsets(u)[1] - self.radius

    def _barrier_gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r""":math:`\kappa b'(d_a)\,n_a` at the active nodes: ``(dofs, values)`` of shape ``(m, dim)``."""
        rows, first, _ = self._active(u)
        q, r = self._offsets(u)
        n = q[rows] / r[rows, None]
        return self.nodes.dofs[rows], self.stiffness * first[:, None] * n

    def _barrier_hessian(self, u: np.ndarray, project: bool = True) -> tuple[np.ndarray, np.ndarray]:
        r"""The blocks :math:`\kappa(b'' n n^T + b'(I - n n^T)/r)` at the active nodes, PSD-projected by default.

        Args:
            u: The unknown's local array.
            project: Project each block onto the PSD cone (the tangent); ``False``: the exact Hessian.

        Returns:
            ``(dofs, blocks)``, blocks of shape ``(m, dim, dim)``.
        """
        rows, first, second = self._active(u)
        q, r = self._offsets(u)
        n = q[rows] / r[rows, None]
        outer = np.einsum("mi,mj->mij", n, n)
        plane = np.eye(n.shape[1]) if self.projector is None else self.projector  # a cylinder: I - a a^T
        tangential = (plane[None, :, :] - outer) / r[rows, None, None]
        blocks = self.stiffness * (second[:, None, None] * outer + first[:, None, None] * tangential)
        return self.nodes.dofs[rows], project_psd(blocks) if project else blocks

    def normals(self, u: np.ndarray) -> np.ndarray:
        """The outward unit vectors :math:`n_a = (x_a - c)/r_a` of the owned nodes."""
        q, r = self._offsets(u)
        return q / r[:, None]
