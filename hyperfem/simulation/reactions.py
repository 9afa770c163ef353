r"""Reaction forces and moments on every Dirichlet boundary, from the residual.

At a converged state the residual vanishes at the free dofs; at a dof that a
Dirichlet condition holds it is the force the support exerts on the body.
:class:`DirichletReactions` assembles the residual *without* boundary
conditions and sums it over the dofs each condition constrains,

.. math::
    F_\Gamma = \sum_{a \in \mathcal{D}_\Gamma} R_a\,e_{i(a)}, \qquad
    M_\Gamma = \sum_{a \in \mathcal{D}_\Gamma} (x_a - c_\Gamma) \times R_a\,e_{i(a)},

where :math:`\mathcal{D}_\Gamma` are the (node, component) dofs held by the
conditions on boundary :math:`\Gamma` (only the components they constrain:
a roller reports the force along its axis, zero in the others),
:math:`x_a = X_a + u_a` the current position of the node and
:math:`c_\Gamma` the reference point: by default the centroid of the boundary
in the reference configuration, :math:`\int_\Gamma X\,dA/|\Gamma|`.

Which residual:

* displacement problem: :math:`R = f_\text{int}(u) - f_\text{ext}(t)`
  (follower loads included), so for a statically determinate body the
  reaction is minus the applied load, e.g. :math:`-\int t\,dA` for the bent
  cantilever;
* three-field problem: the displacement rows of its residual (pressure and
  volume rows are never constrained), so the stress is that of the mixed
  solution; without loads on the boundary this is
  :class:`~hyperfem.problem.ReactionForce`;
* dynamic run (:class:`~hyperfem.dynamics.IncrementalProblem`): the balance of
  momentum at the recorded time :math:`t_{n+1}`, inertia and damping included,

  .. math::
      R = M a_{n+1} + C v_{n+1} + f_\text{int}(u_{n+1}) - f_\text{ext}(t_{n+1}),

  with the run's mass (density, lumping) and Rayleigh damping. This is the
  equation Backward Euler and Newmark solve at :math:`t_{n+1}`, so the free
  rows vanish there too; generalized-:math:`\alpha` balances at
  :math:`t_{n+1-\alpha_f}` instead, and the reaction at :math:`t_{n+1}` then
  carries the scheme's small imbalance.

Forces are in the units of the loads (N for a 3D body in SI units), moments
in N m. A dof that two boundaries' conditions both hold counts in both; the
``total`` set counts every constrained dof once (moment about the origin), so
it is the resultant of all supports.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem, la
from mpi4py import MPI

from hyperfem.errors import ParameterError
from hyperfem.simulation.outputs import Output
from hyperfem.solver.stepping import StepRecord

__all__ = ["TOTAL", "DirichletReactions", "ReactionResult", "Reactions", "dirichlet_boundaries"]

TOTAL = "total"
"""Name of the set that sums every constrained dof once."""

_AXES = "xyz"


@dataclass(frozen=True)
class ReactionResult:
    """Force and moment of one support.

    Attributes:
        force: :math:`F_\\Gamma` (``gdim`` components).
        moment: :math:`M_\\Gamma` about :attr:`point` (3 components; only :math:`M_z` in 2D).
        point: The reference point :math:`c_\\Gamma` (3 coordinates).
    """

    force: np.ndarray
    moment: np.ndarray
    point: np.ndarray

    def columns(self, prefix: str) -> dict[str, float]:
        """``{prefix_Fx: ..., prefix_Fy: ..., [prefix_Fz], prefix_Mx..Mz}`` (2D: ``Fx, Fy, Mz``)."""
        out = {f"{prefix}_F{_AXES[i]}": float(v) for i, v in enumerate(self.force)}
        moments = range(3) if len(self.force) == 3 else (2,)
        out.update({f"{prefix}_M{_AXES[i]}": float(self.moment[i]) for i in moments})
        return out


def dirichlet_boundaries(problem) -> dict[str, list[fem.DirichletBC]]:
    """Boundary name → the DOLFINx conditions that hold dofs there, in the order the problem lists them.

    Args:
        problem: A problem built with hyperfem's boundary conditions (or an
            incremental problem wrapping one).
    """
    base = getattr(problem, "base", problem)
    out: dict[str, list[fem.DirichletBC]] = {}
    for compiled in getattr(base, "_dirichlet", ()):
        out.setdefault(compiled.bc.boundary, []).extend(compiled.dirichlet)
    return out


class DirichletReactions:
    """Reaction force and moment of every Dirichlet boundary of a problem (module docstring).

    Forms are compiled once; each call assembles the residual at the current
    state (collective; every rank gets the same values).

    Args:
        problem: A displacement or three-field problem, or an
            :class:`~hyperfem.dynamics.IncrementalProblem` (inertia and damping included).
        boundaries: Which boundaries (default: every boundary with a Dirichlet condition).
        points: Reference point of the moments: ``None`` (each boundary's
            reference centroid), one point for all, or boundary name → point
            (others: the centroid).
        total: Also report the ``"total"`` set (every constrained dof once,
            moment about the origin).
        state_hooks: Callables run before assembling (refresh quadrature fields
            that depend on the state, as the solver does).

    Raises:
        ParameterError: A named boundary has no Dirichlet condition, or a point
            is not 1 to 3 finite coordinates.
    """

    def __init__(
        self,
        problem,
        boundaries: Sequence[str] | None = None,
        *,
        points: Sequence[float] | Mapping[str, Sequence[float]] | None = None,
        total: bool = True,
        state_hooks: Sequence = (),
    ):
        base = getattr(problem, "base", problem)
        self.problem = problem
        domain = base.domain
        self.comm = domain.comm
        self.gdim = domain.gdim
        self._hooks = list(state_hooks)
        held = dirichlet_boundaries(problem)
        names = list(held) if boundaries is None else list(boundaries)
        for name in names:
            if name not in held:
                raise ParameterError(
                    f"DirichletReactions: boundary {name!r} has no Dirichlet condition "
                    f"(held boundaries: {', '.join(held) or 'none'})"
                )
        state = base.u
        space = base.displacement_space()
        n_state = len(state.x.array)
        owned = state.function_space.dofmap.index_map.size_local * state.function_space.dofmap.index_map_bs
        # Each displacement dof of the state: its node (in the collapsed component space) and component.
        self._node = np.full(n_state, -1, dtype=np.int64)
        self._comp = np.full(n_state, -1, dtype=np.int64)
        self._idx = []
        coordinates = []
        for i in range(self.gdim):
            Vi, dofs = space.sub(i).collapse()
            dofs = np.asarray(dofs, dtype=np.int64).reshape(-1)
            self._node[dofs] = np.arange(len(dofs))
            self._comp[dofs] = i
            self._idx.append(dofs)
            coordinates.append(Vi.tabulate_dof_coordinates())
        if not all(np.array_equal(coordinates[0], c) for c in coordinates):
            raise ParameterError("DirichletReactions: the displacement components are numbered differently per node")
        self._X = coordinates[0]
        self._dofs: dict[str, np.ndarray] = {}
        for name in names:
            d = np.unique(np.concatenate([bc.dof_indices()[0] for bc in held[name]]).astype(np.int64))
            d = d[(d < owned) & (self._comp[d] >= 0)]
            self._dofs[name] = d
        if total:
            every = [bc.dof_indices()[0] for bcs in held.values() for bc in bcs]
            d = np.unique(np.concatenate(every).astype(np.int64)) if every else np.zeros(0, dtype=np.int64)
            self._dofs[TOTAL] = d[(d < owned) & (self._comp[d] >= 0)]
        self.points = {name: self._point(points, name, domain) for name in self._dofs}
        self._residual = fem.form(base.residual)
        self._inertia = self._inertia_form(problem, base)

    @property
    def names(self) -> list[str]:
        """The boundaries reported (and ``"total"``), in order."""
        return list(self._dofs)

    def _point(self, points, name: str, domain) -> np.ndarray:
        if name == TOTAL:
            return np.zeros(3)
        given = points.get(name) if isinstance(points, Mapping) else points
        if given is None:
            ds = domain.ds(name)
            X = ufl.SpatialCoordinate(domain.mesh)
            area = self.comm.allreduce(fem.assemble_scalar(fem.form(1.0 * ds)))
            c = [self.comm.allreduce(fem.assemble_scalar(fem.form(X[k] * ds))) / area for k in range(self.gdim)]
        else:
            try:
                c = [float(v) for v in given]
            except (TypeError, ValueError):
                c = []
            if not 1 <= len(c) <= 3 or not np.all(np.isfinite(c)):
                raise ParameterError(
                    f"DirichletReactions: point of {name!r} must be 1 to 3 finite numbers, got {given!r}"
                )
        return np.array([*c, *[0.0] * (3 - len(c))], dtype=float)

    @staticmethod
    def _inertia_form(problem, base):
        """:math:`M a + C v` tested with the state's test function (dynamic runs), else ``None``."""
        integrator = getattr(problem, "integrator", None)
        if integrator is None or not integrator.dynamic:
            return None
        disp = base.displacement
        test = ufl.TestFunction(base.u.function_space)
        degree = base.degree
        density, domain = problem.density, base.domain
        form = density.integral(ufl.dot(disp(problem.a), disp(test)), domain, degree)
        damping = problem.damping
        if damping is not None:
            from hyperfem.dynamics.damping import reference_stiffness_form

            if damping.alpha:
                form = form + damping.alpha * density.integral(ufl.dot(disp(problem.v), disp(test)), domain, degree)
            if damping.beta:
                embedded = problem.displacement_block.embed(disp(problem.v))
                form = form + damping.beta * reference_stiffness_form(base.energy_internal, base.u, embedded, test)
        return fem.form(form)

    def residual(self) -> np.ndarray:
        """The assembled residual at the current state, without boundary conditions (owned entries complete)."""
        for hook in self._hooks:
            hook()
        out = None
        for form in (self._residual, self._inertia):
            if form is None:
                continue
            vec = fem.assemble_vector(form)
            vec.scatter_reverse(la.InsertMode.add)
            out = vec.array.copy() if out is None else out + vec.array
        return out

    def __call__(self) -> dict[str, ReactionResult]:
        """Boundary name → :class:`ReactionResult` at the current state (collective)."""
        r = self.residual()
        state = getattr(self.problem, "base", self.problem).u.x.array
        x = np.array(self._X, dtype=float)
        for i, dofs in enumerate(self._idx):
            x[:, i] += state[dofs]
        local = np.zeros((len(self._dofs), 6))
        for k, (name, d) in enumerate(self._dofs.items()):
            comps, nodes = self._comp[d], self._node[d]
            f = np.zeros((len(d), 3))
            f[np.arange(len(d)), comps] = r[d]
            local[k, :3] = f.sum(axis=0)
            local[k, 3:] = np.cross(x[nodes] - self.points[name], f).sum(axis=0) if len(d) else 0.0
        total = self.comm.allreduce(local, op=MPI.SUM)
        return {
            name: ReactionResult(total[k, : self.gdim].copy(), total[k, 3:].copy(), self.points[name])
            for k, name in enumerate(self._dofs)
        }


class Reactions(Output):
    """Reaction force and moment of every Dirichlet boundary, at every recorded state (:class:`DirichletReactions`).

    Columns ``<prefix>_<boundary>_Fx, _Fy, _Fz, _Mx, _My, _Mz`` (2D: ``Fx, Fy,
    Mz``) for each boundary and for ``total``; the summary gets
    ``"reactions"``: boundary → ``{"force", "moment", "point"}`` of the last
    state.

    Args:
        boundaries: Which boundaries (default: all with a Dirichlet condition).
        points: Reference points of the moments (default: each boundary's
            reference centroid; see :class:`DirichletReactions`).
        total: Report the ``total`` set.
        prefix: Start of the column names.
    """

    def __init__(
        self,
        boundaries: Sequence[str] | None = None,
        *,
        points: Sequence[float] | Mapping[str, Sequence[float]] | None = None,
        total: bool = True,
        prefix: str = "reaction",
    ):
        self.boundaries = None if boundaries is None else list(boundaries)
        self.points = points
        self.total = total
        self.prefix = prefix
        self.reactions: DirichletReactions | None = None
        self._last: dict[str, ReactionResult] = {}

    def start(self, sim) -> None:
        """Find the constrained dofs and compile the forms."""
        hooks = [*getattr(sim.solver, "state_hooks", ())]
        self.reactions = DirichletReactions(
            sim.problem, self.boundaries, points=self.points, total=self.total, state_hooks=hooks
        )

    def restart(self, sim, state: dict | None) -> None:
        """The reactions of the restart state (for the summary)."""
        self._last = self.reactions()

    def measure(self, sim, step: StepRecord | None) -> dict:
        """The columns of every boundary."""
        self._last = self.reactions()
        row = {}
        for name, result in self._last.items():
            row.update(result.columns(f"{self.prefix}_{name}"))
        return row

    def summary(self, sim, summary: dict) -> dict:
        """The last forces and moments by boundary."""
        if not self._last:
            return {}
        return {
            "reactions": {
                name: {"force": r.force.tolist(), "moment": r.moment.tolist(), "point": r.point.tolist()}
                for name, r in self._last.items()
            }
        }
