r"""Muscle activation :math:`\alpha \in [0, 1]` per region ("contractile units").

An :class:`Activation` is a UFL scalar

.. math::
    \alpha(X, t) = g(t)\, a(X),

where :math:`g` is a constant or a schedule :math:`g(t)` held in a
:class:`dolfinx.fem.Constant` (updated by :meth:`Activation.update` with the
load factor or time :math:`t`), and :math:`a` is 1 or a spatial field. Values
outside :math:`[0, 1]` raise :class:`~hyperfem.errors.ParameterError`.
Pass activations to a problem as ``updaters=[...]``: its
:meth:`~hyperfem.problem.protocol.SolidProblem.set_time` calls ``update(t)``.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable

from mpi4py import MPI

import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

from hyperfem.errors import ParameterError

__all__ = ["Activation"]


def _check_range(value: float, what: str) -> float:
    if not (isinstance(value, numbers.Real) and not isinstance(value, bool)):
        raise ParameterError(f"{what}: activation must be a number in [0, 1], got {value!r}")
    value = float(value)
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise ParameterError(f"{what}: activation must lie in [0, 1], got {value!r}")
    return value


class Activation:
    """Activation of one region.

    Args:
        mesh: The DOLFINx mesh.
        value: A number in [0, 1], or a schedule ``value(t) -> float`` of the
            load factor/time (evaluated at ``t = 0`` initially).
        field: Optional spatial factor: a scalar :class:`dolfinx.fem.Function`
            or a callable ``field(x) -> array`` interpolated into DG0; its
            values must lie in [0, 1].
        name: Label used in error messages.

    Attributes:
        expr: The UFL expression :math:`\\alpha` to pass to the energy.
    """

    def __init__(
        self,
        mesh: dmesh.Mesh,
        value: float | Callable[[float], float] = 0.0,
        field: fem.Function | Callable[[np.ndarray], np.ndarray] | None = None,
        name: str = "activation",
    ) -> None:
        self.name = name
        self._schedule = value if callable(value) else None
        initial = value(0.0) if callable(value) else value
        self.scale = fem.Constant(mesh, _check_range(initial, name))
        self.field: fem.Function | None = None
        if field is not None:
            if isinstance(field, fem.Function):
                self.field = field
            elif callable(field):
                V = fem.functionspace(mesh, ("DG", 0))
                self.field = fem.Function(V, name=name)
                error = ""
                try:  # the callable runs on each rank's own cells: agree before raising
                    self.field.interpolate(lambda x: np.asarray(field(x), dtype=float))
                except Exception as exc:  # noqa: BLE001 - user callable
                    error = (str(exc).splitlines() or [type(exc).__name__])[0]
                errors = [e for e in mesh.comm.allgather(error) if e]
                if errors:
                    raise ParameterError(f"{name}: evaluating the activation field failed: {errors[0]}")
            else:
                raise ParameterError(
                    f"{name}: field must be a dolfinx Function or a callable field(x), got {type(field).__name__}"
                )
            arr = self.field.x.array
            nonfinite = mesh.comm.allreduce(int(np.count_nonzero(~np.isfinite(arr))), op=MPI.SUM)
            if nonfinite:
                raise ParameterError(f"{name}: activation field has {nonfinite} non-finite value(s) (nan or inf)")
            local = (float(arr.min()), float(-arr.max())) if arr.size else (np.inf, np.inf)
            lo, neg_hi = (mesh.comm.allreduce(v, op=MPI.MIN) for v in local)
            if not (lo >= 0.0 and -neg_hi <= 1.0):
                raise ParameterError(f"{name}: activation field must lie in [0, 1], got [{lo:g}, {-neg_hi:g}]")
        self.expr: ufl.core.expr.Expr = self.scale if self.field is None else self.scale * self.field

    @property
    def value(self) -> float:
        """Current value of the time factor :math:`g(t)`."""
        return float(self.scale.value)

    def set(self, value: float) -> None:
        """Set the time factor to a number in [0, 1]."""
        self.scale.value = _check_range(value, self.name)  # type: ignore[assignment]  # dolfinx: any array-like

    def update(self, t: float) -> None:
        """Evaluate the schedule at load factor/time ``t`` (no-op for a constant)."""
        if self._schedule is not None:
            self.set(self._schedule(t))
