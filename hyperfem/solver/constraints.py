r"""Do the Dirichlet conditions of a problem remove every rigid-body motion?

A static problem whose Dirichlet conditions leave a rigid-body motion free
has a singular tangent: SNES then fails in the linear solve or the line
search, far from the cause. The rigid modes :math:`r_k` (translations
:math:`e_i`, rotations :math:`e_i\times X`; 6 in 3D, 3 in 2D, 1 in 1D) are restricted
to the constrained displacement dofs, normalised by their norm over the
whole body, and the Gram matrix :math:`G_{kl} = \sum_{i\in\text{Dirichlet}}
r_k^i r_l^i` is summed over ranks: each (near-)zero eigenvalue is a motion
the conditions do not see. Exact for translations/rotations of the discrete
space, since rigid motions are in every Lagrange space.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI
from dolfinx import fem

if TYPE_CHECKING:
    from hyperfem.problem.protocol import SolidProblem

__all__ = ["rigid_modes", "unconstrained_rigid_modes"]

_NAMES_3D = [
    "translation x",
    "translation y",
    "translation z",
    "rotation about x",
    "rotation about y",
    "rotation about z",
]
_NAMES_2D = ["translation x", "translation y", "rotation"]


def rigid_modes(gdim: int) -> list:
    """Callables ``x -> values`` (shape ``(gdim, n)``) of the rigid-body modes."""
    if gdim == 1:
        return [lambda x: np.ones((1, x.shape[1]))]
    if gdim == 2:
        return [
            lambda x: np.vstack([np.ones_like(x[0]), np.zeros_like(x[0])]),
            lambda x: np.vstack([np.zeros_like(x[0]), np.ones_like(x[0])]),
            lambda x: np.vstack([-x[1], x[0]]),
        ]
    zero, one = np.zeros_like, np.ones_like
    return [
        lambda x: np.vstack([one(x[0]), zero(x[0]), zero(x[0])]),
        lambda x: np.vstack([zero(x[0]), one(x[0]), zero(x[0])]),
        lambda x: np.vstack([zero(x[0]), zero(x[0]), one(x[0])]),
        lambda x: np.vstack([zero(x[0]), -x[2], x[1]]),
        lambda x: np.vstack([x[2], zero(x[0]), -x[0]]),
        lambda x: np.vstack([-x[1], x[0], zero(x[0])]),
    ]


def unconstrained_rigid_modes(problem: SolidProblem, tol: float = 1e-10) -> list[str]:
    """Names of the rigid-body motions left free by ``problem.bcs`` (empty when all are constrained).

    Args:
        problem: A :class:`~hyperfem.problem.protocol.SolidProblem`.
        tol: Eigenvalue threshold of the normalised Gram matrix.
    """
    domain = problem.domain
    comm = domain.comm
    gdim = domain.gdim
    W = problem.u.function_space
    sub = problem.displacement_space() is not W  # the displacement block of a mixed state
    bs = W.dofmap.index_map_bs
    n_owned = W.dofmap.index_map.size_local * bs
    mask = np.zeros(len(problem.u.x.array), dtype=bool)
    for bc in problem.bcs:
        dofs, _ = bc.dof_indices()
        mask[dofs] = True
    mask[n_owned:] = False
    modes = []
    r = fem.Function(W)
    for f in rigid_modes(gdim):
        r.x.array[:] = 0.0
        (r.sub(0) if sub else r).interpolate(f)
        values = r.x.array[:n_owned]
        norm2 = comm.allreduce(float(values @ values), op=MPI.SUM)
        modes.append(values / np.sqrt(norm2) if norm2 > 0 else values)
    R = np.array([m[mask[:n_owned]] for m in modes])
    G = comm.allreduce(R @ R.T, op=MPI.SUM)
    w, vecs = np.linalg.eigh(G)
    names = {1: ["translation x"], 2: _NAMES_2D, 3: _NAMES_3D}[gdim]
    free = []
    for k in np.flatnonzero(w < tol):
        v = np.abs(vecs[:, k])
        j = int(np.argmax(v))
        combination = "a combination of " + ", ".join(names[i] for i in np.flatnonzero(v > 0.1))
        free.append(names[j] if v[j] > 0.99 else combination)
    return free
