r"""Energies of the unknown's nodal values that are not UFL forms (a contact barrier), in the Newton system.

The total potential of a problem with contact is

.. math::
    \Pi(u) = \Pi_\text{elastic}(u) - W_\text{ext}(u) + \sum_e E_e(u),

where each :math:`E_e` (:class:`ExternalEnergy`, e.g. the barrier
:math:`\kappa B(x(u))` of :class:`~hyperfem.contact.PlaneContact`) is
evaluated on the unknown's nodal values in numpy rather than assembled from a
form. :class:`ExternalTerms` adds them to what
:class:`~hyperfem.solver.NewtonSolver` gives SNES:

* the **objective** (the energy line search judges contact too):
  :math:`\sum_e E_e`, summed over the ranks with ``allreduce``;
* the **residual**: :math:`\partial E_e/\partial u` added to the assembled
  vector, except on Dirichlet dofs, whose rows keep :math:`x - g`;
* the **tangent**: the blocks of :math:`\partial^2 E_e/\partial u^2` added to
  the assembled matrix with the rows *and* columns of Dirichlet dofs zeroed,
  so those rows stay identity rows and the columns zero (DOLFINx has applied
  the conditions to the assembled matrix already);
* the **start guess**: a time integrator moves the state before the solve
  (:math:`w_n + \Delta t\,v_n`); where that guess goes through an obstacle
  it is pulled back along the segment from the last state the solver
  converged to, by the energies' step filters (:meth:`ExternalTerms.pull_back`),
  so a dynamic step starts intersection-free instead of failing;
* the **start check**: a state an energy still refuses (an obstacle that moved
  into the body) is not solved from, and nothing is assembled there: the
  solve fails and the stepper cuts back;
* the **step filters** the energies bring (a continuous collision detection),
  composed with the inversion filter.

Node blocks (``hessian``: one block per node, point–obstacle terms) lie in
the finite-element sparsity pattern. An energy whose Hessian couples nodes of
different elements (contact pairs between surfaces) gives its entries as
global ``(rows, cols, values)`` through an optional ``coupled_hessian(u)``;
they are added with PETSc allowed to allocate new nonzeros (the pattern grows
to the union of the pairs ever active, and PETSc redoes the symbolic set-up of
the preconditioner when it grew; :mod:`hyperfem.contact.mesh_barrier`).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Protocol, runtime_checkable

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import SolidProblem
from hyperfem.solver.filters import NewtonStepFilter

__all__ = ["ExternalEnergy", "ExternalTerms"]


@runtime_checkable
class ExternalEnergy(Protocol):
    r"""An energy of the unknown's nodal values that the Newton solver adds to :math:`\Pi` (module docstring).

    Every method takes ``u``, the unknown's local array (``problem.u.x.array``:
    owned entries first, then ghosts), and reports this rank's part: the terms
    of the nodes it owns. Dofs are local indices into ``u``; rows must be owned.

    Attributes:
        step_filter: A filter the solver composes with its inversion filter
            (``None``: the energy needs none).
    """

    step_filter: NewtonStepFilter | None

    def update(self, t: float) -> None:
        """Move to time (load factor) ``t`` (an obstacle's prescribed motion)."""

    def energy(self, u: np.ndarray) -> float:
        """This rank's part of the energy (``inf`` where the state is inadmissible).

        A function of ``u`` alone between :meth:`update` calls: the line search reuses the energy of a
        state it evaluated before (:class:`~hyperfem.solver.objective.EnergyObjective`)."""

    def gradient(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(dofs, values)``, both of shape ``(m, k)``: the gradient entries of ``m`` groups of ``k`` dofs."""

    def hessian(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(dofs, blocks)`` of shapes ``(m, k)`` and ``(m, k, k)``: symmetric blocks, positive semi-definite
        unless the energy says otherwise (``exact_tangent``: a curved obstacle's exact blocks,
        :mod:`hyperfem.contact.nodal`)."""

    def admissible(self, u: np.ndarray) -> str:
        """An empty string where the state is admissible on this rank, else why not (one line)."""


def _add_entries(A: PETSc.Mat, rows: np.ndarray, cols: np.ndarray, values: np.ndarray) -> None:
    """Add global ``(rows, cols, values)`` (rows owned by this rank, duplicates summed) to ``A``, new nonzeros allowed.

    Collective in effect: every rank calls it (with or without entries) before ``A.assemble()``.
    """
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)  # type: ignore[arg-type, unused-ignore]  # an int
    if not len(rows):
        return
    order = np.lexsort((cols, rows))
    rows, cols, values = rows[order], cols[order], values[order]
    unique, starts = np.unique(rows, return_index=True)
    pointers = np.append(starts, len(rows)).astype(PETSc.IntType)
    columns, rowmap = cols.astype(PETSc.IntType), unique.astype(PETSc.IntType)
    A.setValuesIJV(pointers, columns, values, addv=True, rowmap=rowmap)  # type: ignore[arg-type, unused-ignore]


class ExternalTerms:
    """The external energies of one solver, added to its objective, residual and tangent (module docstring).

    Args:
        problem: The problem (its unknown and Dirichlet conditions).
        energies: The energies.

    Raises:
        ParameterError: An entry does not meet :class:`ExternalEnergy`.
    """

    def __init__(self, problem: SolidProblem, energies: Iterable[ExternalEnergy] = ()):
        self.energies: list[ExternalEnergy] = []
        for energy in energies:
            if not isinstance(energy, ExternalEnergy):
                raise ParameterError(
                    "NewtonSolver: an external energy needs step_filter, update(t), energy(u), gradient(u), "
                    f"hessian(u) and admissible(u) (e.g. PlaneContact(...).bind(problem)), got {type(energy).__name__}"
                )
            self.energies.append(energy)
        self.u = problem.u
        self.comm = problem.domain.comm
        W = problem.u.function_space
        index_map, bs = W.dofmap.index_map, W.dofmap.index_map_bs
        blocks = index_map.local_to_global(np.arange(index_map.size_local + index_map.num_ghosts, dtype=np.int32))
        self._global = (blocks[:, None] * bs + np.arange(bs)).ravel().astype(PETSc.IntType)
        self._constrained = np.zeros(len(self._global), dtype=bool)
        for bc in problem.bcs:
            self._constrained[bc.dof_indices()[0]] = True
        # The last state the solver converged to (the state at construction until then): admissible.
        self._anchor = problem.u.x.array.copy()
        self.problem = problem
        self.anchor_time = float(problem.time)
        self._lag()

    def _lag(self) -> None:
        """Let the energies with lagged quantities (friction) take them at the current state (``lag(u)``)."""
        for energy in self.energies:
            lag = getattr(energy, "lag", None)
            if lag is not None:
                lag(self.u.x.array)

    def __bool__(self) -> bool:
        return bool(self.energies)

    @property
    def step_filters(self) -> list[NewtonStepFilter]:
        """The step filters the energies bring."""
        return [e.step_filter for e in self.energies if e.step_filter is not None]

    def update(self, t: float) -> None:
        """Move every energy to time ``t``."""
        for energy in self.energies:
            energy.update(t)

    def energy(self) -> float:
        """The sum of the energies at the unknown's current state (collective)."""
        local = sum((float(e.energy(self.u.x.array)) for e in self.energies), 0.0)
        return float(self.comm.allreduce(local, op=MPI.SUM))

    def gradient_array(self) -> np.ndarray:
        """The gradients at the current state as one array like the unknown's (this rank's rows; Dirichlet rows too).

        What the energies add to the residual of every dof, the constrained ones
        included: the reactions of the supports need it there (a contact node
        with a fixed component pushes on its support).
        """
        out = np.zeros_like(self.u.x.array)
        for energy in self.energies:
            dofs, values = energy.gradient(self.u.x.array)
            np.add.at(out, dofs.ravel(), values.ravel())
        return out

    def add_residual(self, b: PETSc.Vec) -> None:
        """Add the gradients at the current state to the assembled residual ``b``, Dirichlet rows excepted."""
        for energy in self.energies:
            dofs, values = energy.gradient(self.u.x.array)
            values = np.where(self._constrained[dofs], 0.0, values)
            b.setValues(self._global[dofs.ravel()], values.ravel().tolist(), addv=True)  # True: ADD_VALUES
        b.assemble()

    def add_tangent(self, A: PETSc.Mat) -> None:
        """Add the Hessian blocks at the current state to the assembled tangent ``A``.

        The rows and columns of Dirichlet dofs are zeroed in each block, so the
        identity rows and zero columns DOLFINx made there stay exact.
        """
        for energy in self.energies:
            coupled = getattr(energy, "coupled_hessian", None)
            if coupled is not None:
                _add_entries(A, *coupled(self.u.x.array))
            dofs, blocks = energy.hessian(self.u.x.array)
            if not len(dofs):
                continue
            free = ~self._constrained[dofs]
            blocks = blocks * free[:, :, None] * free[:, None, :]
            rows = self._global[dofs]
            A.setValuesRCV(rows, rows, blocks.reshape(len(dofs), -1), addv=PETSc.InsertMode.ADD_VALUES)
        A.assemble()

    def refusal(self) -> str:
        """Why an energy refuses the current state (the first reason over the ranks), or ``""`` (collective)."""
        local = next((why for e in self.energies if (why := e.admissible(self.u.x.array))), "")
        return next((why for why in self.comm.allgather(local) if why), "")

    def remember(self) -> None:
        """Keep the current state as the anchor of :meth:`pull_back` and the friction's lag (after a converged solve).

        The solver calls it after every converged solve (an accepted step; a
        failed solve that is cut back does not), a restart after loading the
        state: an energy's lagged quantities (:meth:`~hyperfem.contact.nodal.NodalBarrier.lag`)
        follow the accepted steps.
        """
        self._anchor[:] = self.u.x.array
        self.anchor_time = float(self.problem.time)
        self._lag()

    def pull_back(self) -> bool:
        r"""Move a refused start guess back toward the anchor, to the fraction the step filters allow (collective).

        With :math:`w_a` the anchor (the last converged state) and :math:`w_g`
        the guess, the state becomes :math:`w_a + \alpha (w_g - w_a)`, where
        :math:`\alpha` is the smallest fraction the energies' step filters give
        the step from :math:`w_a` to :math:`w_g` (their continuous collision
        detection: every node keeps part of its distance). The filters'
        counters are left as they were (this is no Newton step).

        A guess that no energy refuses is still pulled back where a sweep check
        fails (:meth:`sweep_refusal`): a body surface may pass wholly through a
        triangulated tool or another body within one step and end on the far side
        at a positive distance, which the end state alone does not show (a block
        dropped 0.025 onto a plate 0.02 below it did).

        Returns:
            Whether the state moved: ``False`` where the guess is admissible
            already, or where the anchor is refused at the current time too
            (an obstacle moved into the body: the start check then refuses the solve).
        """
        if not self.refusal() and not self.sweep_refusal():
            return False
        guess = self.u.x.array.copy()
        self.u.x.array[:] = self._anchor
        if self.refusal():
            self.u.x.array[:] = guess
            return False
        x = self.u.x.petsc_vec.copy()  # the anchor's owned entries
        y = x.duplicate()
        y.array_w[:] = self._anchor[: len(y.array_r)] - guess[: len(y.array_r)]
        try:
            alpha = 1.0
            for step_filter in self.step_filters:
                kept = (step_filter.filtered_steps, step_filter.min_step_fraction)
                alpha = min(alpha, step_filter.step_fraction(x, y))
                step_filter.filtered_steps, step_filter.min_step_fraction = kept
        finally:
            x.destroy()
            y.destroy()
        self.u.x.array[:] = self._anchor + alpha * (guess - self._anchor)
        return True

    def carry(self) -> tuple[np.ndarray, np.ndarray] | None:
        r"""Put the state back at the anchor and give the increments that carry the nodes an obstacle overran.

        An obstacle that moved into the body since the anchor (a tool pushed
        into tissue that it touches already) makes the anchor inadmissible at
        the new time, and no step filter can pull a guess back into an
        admissible state. Each energy with a prescribed motion names the nodes
        its move would overrun and their increment (``carried(u, t_anchor)``:
        the obstacle's translation, so they keep their place relative to it);
        the solver's predictor prescribes them, with the Dirichlet increments,
        in one tangent solve at the anchor, which carries the push into the
        body (:class:`~hyperfem.solver.predictor.BoundaryPredictor`).
        Dirichlet dofs keep their own values.

        Returns:
            Global dofs (this rank's) and their increments, or ``None`` where no
            energy names any node on any rank, or the anchor itself is refused
            at its own time (collective).
        """
        self.u.x.array[:] = self._anchor
        return self._carried("carried", self._anchor, self.anchor_time)

    def back_to_anchor(self) -> None:
        """Put the state back at the anchor (the last converged state)."""
        self.u.x.array[:] = self._anchor

    def carries_more(self) -> bool:
        """Whether an energy can name the nodes a lift pushed into its obstacle (:meth:`carry_more`)."""
        return any(hasattr(e, "overrun_after_lift") for e in self.energies)

    def carry_more(self, carried: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
        """Add the nodes a lift pushed into an obstacle to ``carried``; put the state back at the anchor.

        The predictor's tangent solve with the carried nodes prescribed moves
        their neighbours too, and can push one that was clear of the obstacle
        into it (a ball dragged across a slab presses the surface ahead of it
        down and forward). Each energy with ``overrun_after_lift(u, anchor,
        t_anchor)`` names the nodes of the lifted state that keep less of
        their distance than carried rigidly with the obstacle from the anchor,
        and their increment; the solver lifts again with them carried too
        (:class:`~hyperfem.solver.newton.NewtonSolver`).

        Returns:
            ``carried`` with the new nodes (global dofs and increments), or
            ``None`` where no energy names a new one on any rank (collective).
        """
        lifted = self.u.x.array.copy()
        self.back_to_anchor()
        more = self._carried("overrun_after_lift", lifted, self._anchor, self.anchor_time)
        if more is None:
            return None
        rows, values = carried
        new = ~np.isin(more[0], rows)
        if not self.comm.allreduce(int(new.sum()), op=MPI.SUM):
            return None
        return np.concatenate([rows, more[0][new]]), np.concatenate([values, more[1][new]])

    def carry_by_supports(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Put the state back at the anchor and give the increments of free nodes that prescribed ones push.

        For the energies with ``carried_by_supports(u, target)`` (mesh contact):
        a Dirichlet-driven surface in contact with another body carries the
        nodes it touches, as an obstacle does (:meth:`carry`); ``None`` where
        none is carried on any rank (collective).
        """
        self.u.x.array[:] = self._anchor
        target = self._anchor.copy()
        for bc in self.problem.bcs:
            bc.set(target)
        return self._carried("carried_by_supports", self._anchor, target)

    def _carried(self, method: str, *args: object) -> tuple[np.ndarray, np.ndarray] | None:
        """The energies' ``method(*args)`` increments: global dofs and values, Dirichlet dofs left out (collective)."""
        rows, values = [], []
        for energy in self.energies:
            carried = getattr(energy, method, None)
            if carried is None:
                continue
            dofs, increments = carried(*args)
            free = ~self._constrained[dofs]
            rows.append(self._global[dofs][free])
            values.append(increments[free])
        local_rows = np.concatenate(rows) if rows else np.zeros(0, dtype=self._global.dtype)
        local_values = np.concatenate(values) if values else np.zeros(0)
        if not self.comm.allreduce(len(local_rows), op=MPI.SUM):
            return None
        return local_rows.astype(PETSc.IntType), local_values.astype(float)

    def sweep_refusal(self) -> str:
        """Why the joint move from the anchor (obstacles at the anchor time) to now is not collision-free, or ``""``.

        For the energies with ``sweep_fraction`` (a triangulated tool: a thin
        body could pass through it between the two end states, which the end
        state's check does not see). Collective.
        """
        for energy in self.energies:
            sweep = getattr(energy, "sweep_fraction", None)
            if sweep is None:
                continue
            fraction = sweep(self._anchor, self.anchor_time, self.u.x.array)
            if fraction < 1.0:
                return (
                    f"{getattr(energy, 'where', 'contact')}: the move from t = {self.anchor_time:g} to "
                    f"t = {self.problem.time:g} sweeps through a surface (collision-free fraction {fraction:.3g})"
                )
        return ""

    def exact_tangents(self) -> bool:
        """Whether an energy gave its exact (possibly indefinite) Hessian at the last tangent."""
        return any(bool(getattr(e, "exact_tangent", False)) for e in self.energies)

    def project_tangents(self) -> None:
        """Let every energy with a choice project its Hessian at the next tangent (``project_tangent()``)."""
        for energy in self.energies:
            project = getattr(energy, "project_tangent", None)
            if project is not None:
                project()
