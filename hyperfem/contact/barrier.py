r"""The IPC log barrier of contact and its derivatives, on arrays of distances.

The barrier of Incremental Potential Contact (Li et al. 2020),

.. math::
    b(d) = -(d - \hat d)^2 \ln\frac{d}{\hat d} \quad (0 < d < \hat d), \qquad
    b(d) = 0 \quad (d \ge \hat d), \qquad b(d) = +\infty \quad (d \le 0),

is :math:`C^2` at :math:`\hat d`, decreasing and convex on :math:`(0, \hat d)`:
:math:`b'(d) \le 0`, :math:`b''(d) > 0`. The values come from the IPC Toolkit's
Python bindings (``ipctk.barrier``, ``barrier_first_derivative``,
``barrier_second_derivative``), which are scalar functions: they are called
for the *active* distances only (:math:`0 < d < \hat d`), about 1.6 µs each.

``ipctk`` is an optional dependency (the extra ``hyperfem[contact]``):
importing :mod:`hyperfem` does not need it, using contact without it raises a
one-line :class:`~hyperfem.errors.ParameterError` naming the extra
(:func:`require_ipctk`).
"""

from __future__ import annotations

from collections.abc import Callable
from types import ModuleType

import numpy as np

from hyperfem.errors import ParameterError

__all__ = ["CONTACT_EXTRA", "barrier", "barrier_derivatives", "require_ipctk"]

CONTACT_EXTRA = "pip install 'hyperfem[contact]'"
"""How to install what contact needs (the IPC Toolkit bindings, PyPI ``ipctk``)."""


def require_ipctk(where: str) -> ModuleType:
    """The ``ipctk`` module, or a one-line :class:`ParameterError` naming the extra when it is not installed.

    Args:
        where: The object that needs it, for the message.
    """
    try:
        import ipctk
    except ImportError:
        raise ParameterError(
            f"{where}: contact needs the IPC Toolkit bindings (ipctk), which are not installed: {CONTACT_EXTRA}"
        ) from None
    return ipctk


def _map(function: Callable[[float, float], float], d: np.ndarray, dhat: float) -> np.ndarray:
    """``function(d_k, dhat)`` for every entry of ``d`` (the ipctk functions are scalar)."""
    return np.fromiter((function(float(x), dhat) for x in d), dtype=float, count=len(d))


def barrier(d: np.ndarray, dhat: float) -> np.ndarray:
    r""":math:`b(d)` per entry (module docstring): ``inf`` where :math:`d \le 0`, 0 where :math:`d \ge \hat d`.

    Args:
        d: Distances.
        dhat: :math:`\hat d > 0`.
    """
    ipctk = require_ipctk("barrier")
    d = np.asarray(d, dtype=float)
    out = np.zeros(d.shape)
    out[d <= 0.0] = np.inf
    active = (d > 0.0) & (d < dhat)
    out[active] = _map(ipctk.barrier, d[active], dhat)
    return out


def barrier_derivatives(d: np.ndarray, dhat: float) -> tuple[np.ndarray, np.ndarray]:
    r""":math:`b'(d)` and :math:`b''(d)` per entry: 0 where :math:`d \ge \hat d`, ``nan`` where :math:`d \le 0`.

    A state with :math:`d \le 0` is never assembled (the solver refuses it and
    the collision filter keeps every trial state out of it); ``nan`` makes a
    violation loud.

    Args:
        d: Distances.
        dhat: :math:`\hat d > 0`.
    """
    ipctk = require_ipctk("barrier_derivatives")
    d = np.asarray(d, dtype=float)
    first = np.zeros(d.shape)
    second = np.zeros(d.shape)
    first[d <= 0.0] = np.nan
    second[d <= 0.0] = np.nan
    active = (d > 0.0) & (d < dhat)
    first[active] = _map(ipctk.barrier_first_derivative, d[active], dhat)
    second[active] = _map(ipctk.barrier_second_derivative, d[active], dhat)
    return first, second
