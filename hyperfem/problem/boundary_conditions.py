"""Dirichlet boundary conditions by physical-group name.

* :class:`Clamp` — all displacement components zero on a boundary.
* :class:`PrescribedDisplacement` — constant, callable or time/load-dependent
  values, on all or selected components.

Values are scaled by ``profile(s)`` where ``s`` is the load factor (or time),
so a prescribed displacement ramps with the load unless a profile says
otherwise. A callable ``value(x, s)`` of two arguments is re-evaluated for
each ``s`` instead (e.g. a rigid rotation of a surface).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.mesh.domain import Domain

__all__ = ["BoundaryCondition", "Clamp", "PrescribedDisplacement", "linear_profile"]


def linear_profile(s: float) -> float:
    """The identity profile: the value is scaled by the load factor ``s``."""
    return s


@dataclass(frozen=True)
class Clamp:
    """Fix every displacement component on a named boundary.

    Attributes:
        boundary: Physical-group name of the boundary.
    """

    boundary: str


@dataclass(frozen=True)
class PrescribedDisplacement:
    """Prescribe displacement components on a named boundary.

    Attributes:
        boundary: Physical-group name of the boundary.
        value: Either a sequence of floats (one per constrained component),
            a callable ``value(x) -> array`` of shape ``(ncomp, npoints)``
            evaluated at the reference coordinates ``x`` (shape ``(3, npoints)``)
            and scaled by ``profile(s)``, or a callable ``value(x, s)`` that is
            re-evaluated at every load factor/time ``s`` (no scaling).
        components: Indices of the constrained components, ``None`` for all.
        profile: Scaling of constant/one-argument values with ``s``.
    """

    boundary: str
    value: Sequence[float] | Callable
    components: Sequence[int] | None = None
    profile: Callable[[float], float] = linear_profile


BoundaryCondition = Clamp | PrescribedDisplacement


class _CompiledDirichlet:
    """A Dirichlet condition bound to a displacement space, updated per load factor.

    ``V`` is the displacement space, or the displacement *subspace* of a mixed
    space (e.g. ``W.sub(0)``), in which case values live on collapsed copies.
    """

    def __init__(self, bc: BoundaryCondition, V: fem.FunctionSpace, domain: Domain):
        fdim = domain.tdim - 1
        facets = domain.facets(bc.boundary)
        gdim = domain.gdim
        if isinstance(bc, Clamp):
            components = list(range(gdim))
            value = None
        else:
            components = list(range(gdim)) if bc.components is None else [int(c) for c in bc.components]
            value = bc.value
            for c in components:
                if not 0 <= c < gdim:
                    raise ParameterError(
                        f"PrescribedDisplacement on {bc.boundary!r}: component {c} outside 0..{gdim - 1}"
                    )
        self.bc = bc
        self._parametric = callable(value) and len(inspect.signature(value).parameters) >= 2
        self._parts = []  # (full function g, working function w, component index or None, components)
        self.dirichlet = []
        whole = components == list(range(gdim))
        is_subspace = len(V.component()) > 0
        if whole:
            spaces = [(V, None, V.collapse()[0] if is_subspace else None)]
        else:
            spaces = [(V.sub(c), c, V.sub(c).collapse()[0]) for c in components]
        for sub, comp, collapsed in spaces:
            W = V if collapsed is None else collapsed
            g = fem.Function(W)
            w = fem.Function(W)
            if collapsed is None:
                dofs = fem.locate_dofs_topological(V, fdim, facets)
                self.dirichlet.append(fem.dirichletbc(w, dofs))
            else:
                dofs = fem.locate_dofs_topological((sub, collapsed), fdim, facets)
                self.dirichlet.append(fem.dirichletbc(w, dofs, sub))
            self._parts.append((g, w, comp, components))
        if value is not None and not self._parametric:
            self._interpolate(value, None)

    def _interpolate(self, value, s: float | None) -> None:
        for g, _, comp, components in self._parts:
            if callable(value):
                f = (lambda x, s=s: np.atleast_2d(value(x, s))) if self._parametric else (
                    lambda x: np.atleast_2d(value(x))
                )
                if comp is None:
                    g.interpolate(f)
                else:
                    row = components.index(comp)
                    g.interpolate(lambda x, f=f, row=row: f(x)[row])
            else:
                vals = [float(v) for v in value]
                if len(vals) != len(components):
                    raise ParameterError(
                        f"PrescribedDisplacement on {self.bc.boundary!r}: {len(vals)} values for "
                        f"{len(components)} components"
                    )
                if comp is None:
                    g.interpolate(lambda x, vals=vals: np.outer(vals, np.ones(x.shape[1])))
                else:
                    v = vals[components.index(comp)]
                    g.interpolate(lambda x, v=v: np.full(x.shape[1], v))

    def update(self, s: float) -> None:
        """Set the boundary values for load factor (or time) ``s``."""
        if isinstance(self.bc, Clamp):
            return
        if self._parametric:
            self._interpolate(self.bc.value, s)
            for g, w, _, _ in self._parts:
                w.x.array[:] = g.x.array
        else:
            scale = float(self.bc.profile(s))
            for g, w, _, _ in self._parts:
                w.x.array[:] = scale * g.x.array
