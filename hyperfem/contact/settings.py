"""The checks every contact shares: barrier width and stiffness, filter safety, friction, profile, name.

One function for :class:`~hyperfem.contact.PlaneContact` and
:class:`~hyperfem.contact.SphereContact` (their obstacle's own entries are
checked by :mod:`~hyperfem.contact.obstacles`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from hyperfem.contact.barrier import require_ipctk
from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import SolidProblem
from hyperfem.validation import check_callable, check_name, check_positive

__all__ = ["check_boundaries", "check_contact_settings", "check_dhat_fits", "check_subdivision"]


def check_contact_settings(
    where: str,
    *,
    dhat: float | None,
    stiffness: float | None,
    safety: float,
    friction: float,
    friction_epsilon: float | None,
    profile: Callable[[float], float],
    name: str,
) -> None:
    """Refuse a bad shared entry of a contact in one line (``where``: ``PlaneContact on 'bottom'``).

    Raises:
        ParameterError: ``dhat``, ``stiffness`` or ``friction_epsilon`` not > 0, ``safety`` outside (0, 1),
            ``friction`` < 0, ``profile`` not callable, a bad ``name``, or ``ipctk`` not installed.
    """
    for key, value in (("dhat", dhat), ("stiffness", stiffness), ("friction_epsilon", friction_epsilon)):
        if value is not None:
            check_positive(key, value, where)
    if not (isinstance(safety, (int, float)) and 0.0 < safety < 1.0):
        raise ParameterError(f"{where}: safety must be a number in (0, 1), got {safety!r}")
    if not (isinstance(friction, (int, float)) and float(friction) >= 0.0 and np.isfinite(friction)):
        raise ParameterError(f"{where}: friction must be a number >= 0, got {friction!r}")
    check_callable(profile, where, "profile")
    check_name(name, "name", where)
    require_ipctk(where)


def check_subdivision(subdivision: object, where: str) -> int | None:
    """The collision proxy's ``subdivision`` (:mod:`~hyperfem.contact.proxy`) as an int, or ``None`` (the default).

    Raises:
        ParameterError: Not ``None`` or an integer from 1 to 8 (one line).
    """
    if subdivision is None:
        return None
    if isinstance(subdivision, bool) or not isinstance(subdivision, (int, np.integer)) or not 1 <= subdivision <= 8:
        raise ParameterError(f"{where}: subdivision must be an integer from 1 to 8, got {subdivision!r}")
    return int(subdivision)


def check_boundaries(boundaries: str | Sequence[str], owner: str) -> tuple[tuple[str, ...], str]:
    """The boundary names of a mesh contact as a tuple, and ``where`` (``ToolContact on ['top']``) for messages.

    Raises:
        ParameterError: No name, a name that is not a valid group name, or a name given twice.
    """
    names = [boundaries] if isinstance(boundaries, str) else list(boundaries)
    where = f"{owner} on {names!r}"
    if not names:
        raise ParameterError(f"{where}: needs at least one boundary group")
    for name in names:
        check_name(name, "boundaries", owner)
    if len(set(names)) != len(names):
        raise ParameterError(f"{where}: a boundary is named twice")
    return tuple(names), where


def check_dhat_fits(problem: SolidProblem, dhat: float, where: str) -> None:
    r"""Refuse a barrier width :math:`\hat d` not below the body's smallest bounding-box side (collective).

    A barrier that reaches across the whole body acts everywhere at once; it is
    a wrong unit or a typo (a width in mm for a mesh in m).

    Raises:
        ParameterError: :math:`\hat d \ge` the smallest side (one line, every rank).
    """
    x = problem.domain.mesh.geometry.x
    gdim, comm = problem.domain.gdim, problem.domain.comm
    local = np.full(2 * gdim, -np.inf)
    if len(x):
        local = np.concatenate([-x[:, :gdim].min(axis=0), x[:, :gdim].max(axis=0)])
    bounds = np.empty_like(local)
    comm.Allreduce(local, bounds, op=MPI.MAX)
    side = float(np.min(bounds[gdim:] + bounds[:gdim]))
    if not dhat < side:
        raise ParameterError(
            f"{where}: dhat = {dhat:g} is not smaller than the body (its bounding box's smallest side is {side:g})"
        )
