"""Dirichlet boundary conditions by physical-group name.

* :class:`Clamp` — all displacement components zero on a boundary.
* :class:`PrescribedDisplacement` — constant, callable or time/load-dependent
  values, on all or selected components.
* :class:`DirichletAgreement` — conditions on boundaries that share nodes
  (an edge between two faces) must prescribe the same value on each shared
  component, at every load factor/time; otherwise one of them would silently
  win on the shared nodes (the last one, in DOLFINx) and the other face would
  not get what it asks for.

Values are scaled by ``profile(s)`` where ``s`` is the load factor (or time),
so a prescribed displacement ramps with the load unless a profile
(:mod:`hyperfem.loading.profiles`) says otherwise. A callable ``value(x, s)`` of two arguments is re-evaluated for
each ``s`` instead (e.g. a rigid rotation of a surface).
"""

from __future__ import annotations

import inspect
import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.loading.profiles import linear_profile
from hyperfem.mesh.domain import Domain
from hyperfem.validation import check_callable, check_finite_vector, check_name

__all__ = ["BoundaryCondition", "Clamp", "DirichletAgreement", "PrescribedDisplacement"]


@dataclass(frozen=True)
class Clamp:
    """Fix every displacement component on a named boundary.

    Attributes:
        boundary: Physical-group name of the boundary.
    """

    boundary: str

    def __post_init__(self) -> None:
        check_name(self.boundary, "boundary", "Clamp")


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

    def __post_init__(self) -> None:
        check_name(self.boundary, "boundary", "PrescribedDisplacement")
        where = f"PrescribedDisplacement on {self.boundary!r}"
        if self.components is not None:
            comps = self.components
            # Boundary: components are user input of any type; only iterability is asked of it.
            if isinstance(comps, (str, bytes)) or not hasattr(comps, "__iter__"):
                raise ParameterError(f"{where}: components must be a sequence of integers, got {comps!r}")
            comps = list(comps)
            if not comps or not all(isinstance(c, numbers.Integral) and not isinstance(c, bool) for c in comps):
                raise ParameterError(f"{where}: components must be a non-empty sequence of integers, got {comps!r}")
            if len(set(comps)) != len(comps):
                raise ParameterError(f"{where}: components {comps} contain duplicates")
        if not callable(self.value):
            values = check_finite_vector(self.value, where)
            if self.components is not None and len(values) != len(list(self.components)):
                raise ParameterError(f"{where}: {len(values)} values for {len(list(self.components))} components")
        check_callable(self.profile, where, "profile")


BoundaryCondition = Clamp | PrescribedDisplacement


class _CompiledDirichlet:
    """A Dirichlet condition bound to a displacement space, updated per load factor.

    ``V`` is the displacement space, or the displacement *subspace* of a mixed
    space (e.g. ``W.sub(0)``), in which case values live on collapsed copies.
    """

    def __init__(self, bc: BoundaryCondition, V: fem.FunctionSpace, domain: Domain):
        if not isinstance(bc, (Clamp, PrescribedDisplacement)):
            raise ParameterError(
                f"boundary conditions must be Clamp or PrescribedDisplacement, got {type(bc).__name__}"
            )
        fdim = domain.tdim - 1
        facets = domain.facets(bc.boundary)
        domain.mesh.topology.create_connectivity(fdim, domain.tdim)
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
        self._boundary_dofs = []  # per part: blocked dofs of g's space on the boundary
        whole = components == list(range(gdim))
        is_subspace = len(V.component()) > 0
        spaces: list[tuple[fem.FunctionSpace, int | None, fem.FunctionSpace | None]]
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
            self._boundary_dofs.append(fem.locate_dofs_topological(W, fdim, facets))
        # Callable values are interpolated on the cells that hold a boundary dof only (the rest is
        # unused): measured 5.3 ms -> 0.22 ms per time step for a rotating end on 10k tets. Not the
        # cells next to this rank's boundary facets: a dof on the boundary can be owned by a rank
        # that has none of its facets, and that owner must still compute its value (on 2 ranks a
        # 4x4x4 cube missed one owned dof that way, and its node did not move).
        held = np.zeros(domain.mesh.topology.index_map(domain.tdim).size_local
                        + domain.mesh.topology.index_map(domain.tdim).num_ghosts, dtype=bool)
        for (g, _, _, _), dofs in zip(self._parts, self._boundary_dofs, strict=True):
            cell_dofs = g.function_space.dofmap.list
            held[: cell_dofs.shape[0]] |= np.isin(cell_dofs, dofs).any(axis=1)
        self._cells = np.flatnonzero(held).astype(np.int32)
        if value is not None and not self._parametric:
            self._interpolate(value, None)

    def _interpolate(self, value: Sequence[float] | Callable[..., np.ndarray], s: float | None) -> None:
        where = f"PrescribedDisplacement on {self.bc.boundary!r}"
        at = "" if s is None else f" at load factor/time {s:g}"
        comm = self._parts[0][0].function_space.mesh.comm
        if not callable(value):  # validated on construction
            self._interpolate_parts(value, s)
            return
        # The callable runs on every rank's own points: agree on failure before raising.
        error = ""
        try:
            self._interpolate_parts(value, s)
        except Exception as exc:  # noqa: BLE001 - user callable; reported on every rank
            error = (str(exc).splitlines() or [type(exc).__name__])[0]
        errors = [e for e in comm.allgather(error) if e]
        if errors:
            raise ParameterError(f"{where}: evaluating the value{at} failed: {errors[0]}")
        for g, _, _, _ in self._parts:
            # Interpolation on the boundary's cells leaves the ghost copies of their dofs
            # untouched; a Dirichlet dof that is a ghost here must hold its owner's value
            # (the ghosts kept the previous one and 2-rank solves stalled). After the error
            # agreement: a rank whose callable failed must not leave the others in the scatter.
            g.x.scatter_forward()
        bad = 0
        for (g, _, _, _), dofs in zip(self._parts, self._boundary_dofs, strict=True):
            bs = g.function_space.dofmap.index_map_bs
            bad += int(np.count_nonzero(~np.isfinite(g.x.array.reshape(-1, bs)[dofs])))
        bad = comm.allreduce(bad, op=MPI.SUM)
        if bad:
            raise ParameterError(f"{where}: the value{at} is not finite (nan or inf) at {bad} boundary value(s)")

    def _interpolate_parts(self, value: Sequence[float] | Callable[..., np.ndarray], s: float | None) -> None:
        for g, _, comp, components in self._parts:
            if callable(value):
                f: Callable[..., np.ndarray] = (
                    (lambda x, s=s: np.atleast_2d(value(x, s)))
                    if self._parametric
                    else (lambda x: np.atleast_2d(value(x)))
                )
                if comp is None:
                    g.interpolate(f, cells0=self._cells)
                else:
                    row = components.index(comp)
                    g.interpolate(lambda x, f=f, row=row: f(x)[row], cells0=self._cells)
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
            if not np.isfinite(scale):
                raise ParameterError(
                    f"PrescribedDisplacement on {self.bc.boundary!r}: profile({s:g}) = {scale!r} is not finite"
                )
            for g, w, _, _ in self._parts:
                w.x.array[:] = scale * g.x.array


def _label(index: int, bc: BoundaryCondition) -> str:
    return f"bc[{index}] ({type(bc).__name__} on {bc.boundary!r})"


class DirichletAgreement:
    r"""Refuse conditions that prescribe different values on the dofs they share.

    Two conditions on different boundaries share the dofs of the nodes where
    the boundaries meet (an edge, a corner). Where both prescribe the same
    component there, the values must agree: a :class:`Clamp` on two adjacent
    faces does, a clamp next to a moving face does not (the shared edge cannot
    be both fixed and moved; before this check the last condition won without
    a word and the run went on to min J 0.08). Pairs that share constrained
    dofs are found once; their values are compared after every update.

    Args:
        compiled: The compiled conditions, in the order the user gave them.
        size: Length of the local array of the state (owned and ghost dofs).
        owned: How many of those this rank owns (the count of disagreeing dofs is over owned ones).
        comm: The mesh communicator.
        rtol: Relative tolerance of the comparison: relative to the largest
            prescribed magnitude of the pair or to ``length``, whichever is larger
            (values computed from coordinates are zero only to round-off).
        length: Length scale of the body (e.g. its bounding-box diagonal).
    """

    def __init__(
        self,
        compiled: Sequence[_CompiledDirichlet],
        size: int,
        owned: int,
        comm: MPI.Comm,
        rtol: float = 1e-9,
        length: float = 1.0,
    ):
        self._compiled = list(compiled)
        self.length = float(length)
        self._size = int(size)
        self._comm = comm
        self.rtol = float(rtol)
        masks = [np.isfinite(self._values(c)) for c in self._compiled]
        pairs = []
        for j in range(len(masks)):
            for i in range(j):
                shared = np.flatnonzero(masks[i][:owned] & masks[j][:owned])
                if comm.allreduce(int(shared.size), op=MPI.SUM):
                    pairs.append((i, j, shared))
        self._pairs = pairs

    def _values(self, c: _CompiledDirichlet) -> np.ndarray:
        values = np.full(self._size, np.nan)
        for d in c.dirichlet:
            d.set(values)
        return values

    @property
    def parametric(self) -> bool:
        """Whether a condition of a sharing pair is given as ``value(x, s)`` (re-evaluated at every ``s``)."""
        return any(self._compiled[k]._parametric for i, j, _ in self._pairs for k in (i, j))

    @property
    def pairs(self) -> list[tuple[int, int]]:
        """Indices of the pairs of conditions that constrain common dofs."""
        return [(i, j) for i, j, _ in self._pairs]

    def check(self, t: float) -> None:
        """Raise :class:`~hyperfem.errors.ParameterError` (on every rank) if a pair disagrees at ``t``.

        Collective over the mesh communicator.
        """
        for i, j, shared in self._pairs:
            a = self._values(self._compiled[i])[shared]
            b = self._values(self._compiled[j])[shared]
            scale = float(np.max(np.abs(np.concatenate([a, b])), initial=0.0))
            diff = np.abs(a - b)
            scale = max(self._comm.allreduce(scale, op=MPI.MAX), self.length)
            bad = diff > self.rtol * scale
            count = self._comm.allreduce(int(np.count_nonzero(bad)), op=MPI.SUM)
            if count:
                worst = self._comm.allreduce(float(np.max(diff, initial=0.0)), op=MPI.MAX)
                ci, cj = self._compiled[i].bc, self._compiled[j].bc
                raise ParameterError(
                    f"{_label(j, cj)} and {_label(i, ci)} prescribe different values on {count} dof(s) "
                    f"of the nodes their boundaries share (at load factor/time {t:g}, differing by up to "
                    f"{worst:.3g}); a node cannot follow both: use boundary groups that do not share nodes, "
                    "or constrain only components that agree there"
                )
