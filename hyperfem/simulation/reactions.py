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
in the reference configuration, :math:`\int_\Gamma X\,dA/|\Gamma|`. At a
dof that other boundaries hold too, :math:`R_a` is replaced by this
boundary's share :math:`R^\Gamma_a` (below).

Which residual:

* displacement problem: :math:`R = f_\text{int}(u) - f_\text{ext}(t)`
  (follower loads included), so for a statically determinate body the
  reaction is minus the applied load, e.g. :math:`-\int t\,dA` for the bent
  cantilever;
* three-field problem: the displacement rows of its residual (pressure and
  volume rows are never constrained), so the stress is that of the mixed
  solution; without loads on the boundary this is
  :class:`ReactionForce`;
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
in N m. The ``total`` set counts every constrained dof once, so it is the
resultant of all supports; its moment is about the **origin**, that of a
boundary about its own reference centroid (or the point given), so on a body
with a single support the two moments differ by :math:`(c_\Gamma - 0)\times F`.
Every result carries its point (:attr:`ReactionResult.point`, ``"point"`` in
the summary).

**Dofs that several boundaries hold** (a node on the edge where two
Dirichlet faces meet, for a component that both constrain): the residual
there is the consistent nodal force of *both* faces' tractions,
:math:`R_a = \int_{\Gamma_1} t\,\varphi_a\,dA + \int_{\Gamma_2} t\,\varphi_a\,dA`,
and which part is whose is not in the residual. Two ways to share it
(``shared=``):

* ``"traction"`` (default): each face gets its own traction's part, taken from
  the stress of the solution, :math:`b^\Gamma_a = \int_\Gamma (P N)\cdot e_{i(a)}\,\varphi_a\,dA`,
  and the rest of the nodal force, :math:`R_a - \sum_{\Gamma'} b^{\Gamma'}_a`,
  in equal parts,

  .. math::
      R^\Gamma_a = b^\Gamma_a + \frac{1}{n_a}\Bigl(R_a - \sum_{\Gamma' \ni a} b^{\Gamma'}_a\Bigr),

  :math:`n_a` the number of boundaries holding dof :math:`a`. The shares add
  up to :math:`R_a`, so the boundaries still sum to ``total``; the rest
  vanishes for a homogeneous state (each face's force is then exact) and
  otherwise is the discrete imbalance at the node, so the error of a face's
  force is the stress error times the strip of cells along the edge, not
  the whole strip of its neighbour's traction. Dofs that one boundary holds
  keep their whole :math:`R_a`: where nothing is shared both ways agree.
  Energies with fields on quadrature points (polar rotations) have no stress
  on facets; there the whole :math:`R_a` is shared in equal parts.
* ``"nodal"``: the whole :math:`R_a` counts for every boundary that holds
  the dof (the classic nodal sum, e.g. Abaqus' RF summed over a node set).
  A face then also carries a strip of each neighbour's traction, an error of
  order :math:`h`; the faces do not sum to ``total``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np
import ufl
from dolfinx import fem, la
from mpi4py import MPI
from ufl.algorithms import extract_coefficients

from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import (
    MixedProblemProtocol,
    SolidProblem,
    StateHookedProblem,
    TimeStepProblem,
    TimeStepState,
)
from hyperfem.simulation.outputs import Output
from hyperfem.solver.stepping import StepRecord

if TYPE_CHECKING:
    from dolfinx import mesh as dmesh

    from hyperfem.dynamics.incremental import IncrementalProblem
    from hyperfem.mesh.domain import Domain
    from hyperfem.simulation.runner import Simulation

__all__ = [
    "SHARED",
    "TOTAL",
    "DirichletReactions",
    "ReactionForce",
    "ReactionResult",
    "Reactions",
    "dirichlet_boundaries",
]

TOTAL = "total"
"""Name of the set that sums every constrained dof once (moment about the origin)."""

SHARED = ("traction", "nodal")
"""Ways to share a dof that several boundaries hold (module docstring); the first is the default."""

_AXES = "xyz"


@dataclass(frozen=True)
class ReactionResult:
    """Force and moment of one support.

    Attributes:
        force: :math:`F_\\Gamma` (``gdim`` components).
        moment: :math:`M_\\Gamma` about :attr:`point` (3 components; only :math:`M_z` in 2D).
        point: The reference point :math:`c_\\Gamma` of the moment (3 coordinates).
        about: What :attr:`point` is, in words: ``"reference centroid of 'x1'"``,
            ``"given point"`` or ``"origin"`` (the ``total`` set).
    """

    force: np.ndarray
    moment: np.ndarray
    point: np.ndarray
    about: str = "given point"

    def columns(self, prefix: str) -> dict[str, float]:
        """``{prefix_Fx, prefix_Fy, [prefix_Fz], prefix_Mx..Mz}`` (2D: ``Fx, Fy, Mz``), moments about :attr:`point`."""
        out = {f"{prefix}_F{_AXES[i]}": float(v) for i, v in enumerate(self.force)}
        moments = range(3) if len(self.force) == 3 else (2,)
        out.update({f"{prefix}_M{_AXES[i]}": float(self.moment[i]) for i in moments})
        return out


def dirichlet_boundaries(problem: SolidProblem | TimeStepState) -> dict[str, list[fem.DirichletBC]]:
    """Boundary name → the DOLFINx conditions that hold dofs there, in the order the problem lists them.

    Args:
        problem: A problem built with hyperfem's boundary conditions (or an
            incremental problem wrapping one).
    """
    base = problem.base if isinstance(problem, TimeStepState) else problem
    out: dict[str, list[fem.DirichletBC]] = {}
    # Boundary: only problems built on hyperfem's EnergyProblem hold compiled conditions.
    for compiled in getattr(base, "_dirichlet", ()):
        out.setdefault(compiled.bc.boundary, []).extend(compiled.dirichlet)
    return out


def _on_quadrature_points(expr: ufl.core.expr.Expr) -> bool:
    """Whether ``expr`` holds a function on quadrature points (which has no values on facets)."""
    for c in extract_coefficients(expr):
        element = c.ufl_function_space().ufl_element()
        if "quadrature" in type(element).__name__.lower():
            return True
    return False


def _region_indicator(itg: ufl.Integral, mesh: dmesh.Mesh) -> ufl.core.expr.Expr | None:
    """1 on the cells of a cell integral's subdomain (a DG0 function), ``None`` for the whole mesh."""
    ids = itg.subdomain_id()
    if ids in ("everywhere", "otherwise"):
        return None
    tags = ids if isinstance(ids, tuple) else (ids,)
    chi = fem.Function(fem.functionspace(mesh, ("DG", 0)))
    data = itg.subdomain_data()
    for tag in tags:
        chi.x.array[data.find(int(tag))] = 1.0
    chi.x.scatter_forward()
    return chi


def first_piola_stress(base: SolidProblem) -> ufl.core.expr.Expr | None:
    r""":math:`P` of a problem's stored energy as a UFL expression valid on boundary facets, or ``None``.

    :math:`P_{ij} = \partial\psi/\partial u\,[x_j e_i]` for the integrand
    :math:`\psi` of each cell integral of :math:`\Pi_\text{int}` (the direction
    :math:`x_j e_i` has gradient :math:`e_i\otimes e_j`; the other fields of a
    three-field state are held, so its pressure term is included), weighted
    by the indicator of the integral's region. ``None`` where the energy holds
    fields on quadrature points.
    """
    mesh = base.domain.mesh
    gdim = base.domain.gdim
    X = ufl.SpatialCoordinate(mesh)
    n = base.u.ufl_shape[0]  # the displacement comes first in a mixed state
    P = None
    for itg in base.energy_internal.integrals():
        if itg.integral_type() != "cell":
            continue
        psi = itg.integrand()
        if _on_quadrature_points(psi):
            return None
        def along(i: int, j: int) -> ufl.core.expr.Expr:  # the direction x_j e_i (zero in the other fields)
            return ufl.as_vector([X[j] if k == i else 0.0 for k in range(n)])

        part = ufl.as_matrix([[ufl.derivative(psi, base.u, along(i, j)) for j in range(gdim)] for i in range(gdim)])
        chi = _region_indicator(itg, mesh)
        part = part if chi is None else chi * part
        P = part if P is None else P + part
    return P


class ReactionForce:
    r"""Total force :math:`\int_\Gamma P N\,dA` exerted on the body at a named (Dirichlet) boundary.

    Computed from the residual of the stored energy,
    :math:`R_i = \partial\Pi_\text{int}/\partial u\,[e_i \chi_\Gamma]`, with
    :math:`\chi_\Gamma` the finite-element function that is 1 at the dofs of
    the boundary and 0 elsewhere (exact for the discrete equilibrium). The
    form is compiled once.

    On a time step (:class:`~hyperfem.dynamics.IncrementalProblem`) it is the
    stored energy of the state :math:`u_{n+1}`, the force at :math:`t_{n+1}`
    without inertia. (The step's own internal energy is that of generalized-α's
    :math:`u_{n+1-\alpha_f}`: its force would lag by :math:`\alpha_f\,\Delta t`, 4.4 %
    of a bar pulled at a constant rate over ten steps with :math:`\rho_\infty = 0.8`.)

    Args:
        problem: A :class:`~hyperfem.problem.HyperelasticProblem` or
            :class:`~hyperfem.problem.MixedHyperelasticProblem` (or an object wrapping one,
            such as a time step).
        boundary: Boundary name.
    """

    def __init__(self, problem: SolidProblem | TimeStepState, boundary: str) -> None:
        if isinstance(problem, TimeStepState):
            problem = problem.base
        domain = problem.domain
        self.comm = domain.comm
        W = problem.u.function_space
        mixed = isinstance(problem, MixedProblemProtocol) and problem.saddle_point
        Vu = W.sub(0) if mixed else W
        self._test = fem.Function(W)
        fdim = domain.tdim - 1
        facets = domain.facets(boundary)
        self._dofs = []
        for i in range(domain.gdim):
            sub = Vu.sub(i)
            collapsed = sub.collapse()[0]
            self._dofs.append(fem.locate_dofs_topological((sub, collapsed), fdim, facets)[0])
        self._form = fem.form(ufl.derivative(problem.energy_internal, problem.u, self._test))

    def __call__(self) -> np.ndarray:
        """The force vector (all ranks get the same values)."""
        out = np.zeros(len(self._dofs))
        for i, dofs in enumerate(self._dofs):
            self._test.x.array[:] = 0.0
            self._test.x.array[dofs] = 1.0
            out[i] = fem.assemble_scalar(self._form)
        return self.comm.allreduce(out)


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
            (others: the centroid). The ``total`` set's moment is always about the origin.
        total: Also report the ``"total"`` set (every constrained dof once,
            moment about the origin).
        state_hooks: Callables run before assembling (refresh quadrature fields
            that depend on the state, as the solver does).
        shared: How a dof that several boundaries hold is shared between them:
            ``"traction"`` (default: each its own traction, from the stress) or
            ``"nodal"`` (the whole nodal force to each); module docstring.
        external: The gradient of energies from outside UFL (contact) at every dof of this rank,
            added to the residual (``NewtonSolver.external.gradient_array``): a contact node
            with a fixed component pushes on its support.

    Raises:
        ParameterError: A named boundary has no Dirichlet condition, a point
            is not 1 to 3 finite coordinates, or ``shared`` is not one of :data:`SHARED`.
    """

    def __init__(
        self,
        problem: SolidProblem | TimeStepState,
        boundaries: Sequence[str] | None = None,
        *,
        points: Sequence[float] | Mapping[str, Sequence[float]] | None = None,
        total: bool = True,
        state_hooks: Sequence[Callable[[], None]] = (),
        shared: str = "traction",
        external: Callable[[], np.ndarray] | None = None,
    ) -> None:
        if shared not in SHARED:
            raise ParameterError(f"DirichletReactions: shared must be one of {', '.join(SHARED)}, got {shared!r}")
        self._external = external
        base = problem.base if isinstance(problem, TimeStepState) else problem
        self.problem = problem
        self.shared = shared
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
            Vi, collapsed = space.sub(i).collapse()
            dofs = np.asarray(collapsed, dtype=np.int64).reshape(-1)
            self._node[dofs] = np.arange(len(dofs))
            self._comp[dofs] = i
            self._idx.append(dofs)
            coordinates.append(Vi.tabulate_dof_coordinates())
        if not all(np.array_equal(coordinates[0], c) for c in coordinates):
            raise ParameterError("DirichletReactions: the displacement components are numbered differently per node")
        self._X = coordinates[0]

        def owned_dofs(bcs: Sequence[fem.DirichletBC]) -> np.ndarray:
            every = [bc.dof_indices()[0] for bc in bcs]
            d = np.unique(np.concatenate(every).astype(np.int64)) if every else np.zeros(0, dtype=np.int64)
            return d[(d < owned) & (self._comp[d] >= 0)]

        self._held = {name: owned_dofs(bcs) for name, bcs in held.items()}
        self._dofs: dict[str, np.ndarray] = {name: self._held[name] for name in names}
        if total:
            self._dofs[TOTAL] = owned_dofs([bc for bcs in held.values() for bc in bcs])
        self._count = np.zeros(n_state, dtype=np.int64)  # boundaries holding each dof
        for d in self._held.values():
            self._count[d] += 1
        self._centroid: set[str] = set()  # boundaries whose moment is about their reference centroid
        self.points = {name: self._point(points, name, domain) for name in self._dofs}
        self._residual = fem.form(base.residual)
        self._inertia = self._inertia_form(problem, base)
        self._traction: fem.Form | None = None
        self._selector: dict[str, fem.Constant] = {}
        if shared == "traction" and self.comm.allreduce(int(np.any(self._count > 1)), op=MPI.MAX):
            self._traction_forms(base, list(held))

    @property
    def names(self) -> list[str]:
        """The boundaries reported (and ``"total"``), in order."""
        return list(self._dofs)

    def about(self, name: str) -> str:
        """What the reference point of ``name``'s moment is, in words."""
        if name == TOTAL:
            return "origin"
        return f"reference centroid of {name!r}" if name in self._centroid else "given point"

    def _point(
        self, points: Sequence[float] | Mapping[str, Sequence[float]] | None, name: str, domain: Domain
    ) -> np.ndarray:
        """The reference point of ``name``'s moment (records which are centroids)."""
        if name == TOTAL:
            return np.zeros(3)
        given = points.get(name) if isinstance(points, Mapping) else points
        if given is None:
            self._centroid.add(name)
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

    def _traction_forms(self, base: SolidProblem, names: list[str]) -> None:
        r"""One form :math:`\sum_\Gamma s_\Gamma \int_\Gamma (P N)\cdot v\,dA` over the boundaries that share dofs.

        Assembled once per boundary with its selector :math:`s_\Gamma = 1`, the others 0.
        """
        P = first_piola_stress(base)
        if P is None:  # no stress on facets: the residual is shared in equal parts
            return
        domain = base.domain
        N = ufl.FacetNormal(domain.mesh)
        test = base.displacement(ufl.TestFunction(base.u.function_space))
        md = {"quadrature_degree": base.quadrature_degree}
        form: ufl.Form | None = None
        for name in names:
            s = fem.Constant(domain.mesh, 0.0)
            self._selector[name] = s
            term = s * ufl.dot(ufl.dot(P, N), test) * domain.ds(name, metadata=md)
            form = term if form is None else form + term
        assert form is not None  # names holds the boundaries that share dofs: two at least
        self._traction = fem.form(form)

    def _own_traction(self, name: str) -> np.ndarray:
        r""":math:`b^\Gamma_a` of boundary ``name`` at every local dof (owned entries complete)."""
        for other, s in self._selector.items():
            s.value = 1.0 if other == name else 0.0  # type: ignore[assignment]  # dolfinx: any array-like
        vec = fem.assemble_vector(self._traction)
        vec.scatter_reverse(la.InsertMode.add)
        return vec.array.copy()

    @staticmethod
    def _inertia_form(problem: SolidProblem | TimeStepState, base: SolidProblem) -> fem.Form | None:
        """:math:`M a + C v` tested with the state's test function (dynamic runs), else ``None``."""
        integrator = problem.integrator if isinstance(problem, TimeStepProblem) else None
        if integrator is None or not integrator.dynamic:
            return None
        problem = cast("IncrementalProblem", problem)  # the dynamic time step (the explicit scheme has no integrator)
        disp = base.displacement
        test = ufl.TestFunction(base.u.function_space)
        degree = base.degree
        density, domain = problem.density, base.domain
        assert density is not None  # a dynamic step has a mass density
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
        out: np.ndarray | None = None
        for form in (self._residual, self._inertia):
            if form is None:
                continue
            vec = fem.assemble_vector(form)
            vec.scatter_reverse(la.InsertMode.add)
            out = vec.array.copy() if out is None else out + vec.array
        assert out is not None  # the residual form is always there
        if self._external is not None:  # energies from outside UFL (contact) act on the supports too
            out = out + self._external()
        return out

    def shares(self, r: np.ndarray | None = None) -> dict[str, np.ndarray]:
        r"""Boundary name → its part of the residual at each of its dofs, in the order of its dofs.

        ``total`` gets the whole :math:`R_a` of every constrained dof.

        With ``shared="nodal"`` every part is the whole :math:`R_a`; with
        ``"traction"`` a dof several boundaries hold is shared as in the
        module docstring. Collective when ``r`` is ``None`` (it is assembled).
        """
        r = self.residual() if r is None else r
        out = {}
        own: dict[str, np.ndarray] = {}
        if self.shared == "traction" and self._traction is not None:
            own = {name: self._own_traction(name) for name in self._selector}
        rest = r.copy()  # R_a minus the own tractions of the boundaries that hold dof a
        for name, b in own.items():
            rest[self._held[name]] -= b[self._held[name]]
        for name, d in self._dofs.items():
            part = r[d].copy()
            if name != TOTAL and self.shared == "traction":
                many = self._count[d] > 1
                n = self._count[d][many]
                if own:
                    part[many] = own[name][d[many]] + rest[d[many]] / n
                else:
                    part[many] = r[d[many]] / n
            out[name] = part
        return out

    def __call__(self) -> dict[str, ReactionResult]:
        """Boundary name → :class:`ReactionResult` at the current state (collective)."""
        parts = self.shares()
        state = (self.problem.base if isinstance(self.problem, TimeStepState) else self.problem).u.x.array
        x = np.array(self._X, dtype=float)
        for i, dofs in enumerate(self._idx):
            x[:, i] += state[dofs]
        local = np.zeros((len(self._dofs), 6))
        for k, (name, d) in enumerate(self._dofs.items()):
            comps, nodes = self._comp[d], self._node[d]
            f = np.zeros((len(d), 3))
            f[np.arange(len(d)), comps] = parts[name]
            local[k, :3] = f.sum(axis=0)
            local[k, 3:] = np.cross(x[nodes] - self.points[name], f).sum(axis=0) if len(d) else 0.0
        total = self.comm.allreduce(local, op=MPI.SUM)
        return {
            name: ReactionResult(total[k, : self.gdim].copy(), total[k, 3:].copy(), self.points[name], self.about(name))
            for k, name in enumerate(self._dofs)
        }


class Reactions(Output):
    """Reaction force and moment of every Dirichlet boundary, at every recorded state (:class:`DirichletReactions`).

    Columns ``<prefix>_<boundary>_Fx, _Fy, _Fz, _Mx, _My, _Mz`` (2D: ``Fx, Fy,
    Mz``) for each boundary and for ``total``; a boundary's moments are about
    its reference centroid (or the point given), the ``total`` set's about the
    origin. The summary gets ``"reactions"``: boundary → ``{"force",
    "moment", "point", "about", "shared"}`` of the last state (``point`` the
    reference point of the moment, ``about`` what it is in words, ``shared``
    how dofs held by several boundaries were shared).

    Args:
        boundaries: Which boundaries (default: all with a Dirichlet condition).
        points: Reference points of the moments (default: each boundary's
            reference centroid; see :class:`DirichletReactions`).
        total: Report the ``total`` set.
        prefix: Start of the column names.
        shared: ``"traction"`` (default) or ``"nodal"`` (:class:`DirichletReactions`).
    """

    def __init__(
        self,
        boundaries: Sequence[str] | None = None,
        *,
        points: Sequence[float] | Mapping[str, Sequence[float]] | None = None,
        total: bool = True,
        prefix: str = "reaction",
        shared: str = "traction",
    ):
        if shared not in SHARED:
            raise ParameterError(f"Reactions: shared must be one of {', '.join(SHARED)}, got {shared!r}")
        self.boundaries = None if boundaries is None else list(boundaries)
        self.points = points
        self.total = total
        self.prefix = prefix
        self.shared = shared
        self.reactions: DirichletReactions | None = None
        self._last: dict[str, ReactionResult] = {}

    def start(self, sim: Simulation) -> None:
        """Find the constrained dofs and compile the forms."""
        external = None
        if sim.solver is not None:
            hooks = [*sim.solver.state_hooks]
            external = sim.solver.external.gradient_array if sim.solver.external else None
        else:  # a problem that steps itself (explicit): the hooks of the body's energies
            base = sim.fields.base
            hooks = [*base.state_hooks] if isinstance(base, StateHookedProblem) else []
        self.reactions = DirichletReactions(
            sim.problem, self.boundaries, points=self.points, total=self.total, state_hooks=hooks, shared=self.shared,
            external=external,
        )

    def restart(self, sim: Simulation, state: dict | None) -> None:
        """The reactions of the restart state (for the summary)."""
        assert self.reactions is not None  # built by start
        self._last = self.reactions()

    def measure(self, sim: Simulation, step: StepRecord | None) -> dict:
        """The columns of every boundary."""
        assert self.reactions is not None  # built by start
        self._last = self.reactions()
        row: dict[str, float] = {}
        for name, result in self._last.items():
            row.update(result.columns(f"{self.prefix}_{name}"))
        return row

    def summary(self, sim: Simulation, summary: dict) -> dict:
        """The last forces and moments by boundary, with the moments' reference points."""
        if not self._last:
            return {}
        return {
            "reactions": {
                name: {
                    "force": r.force.tolist(),
                    "moment": r.moment.tolist(),
                    "point": r.point.tolist(),
                    "about": r.about,
                    "shared": self.shared,
                }
                for name, r in self._last.items()
            }
        }
