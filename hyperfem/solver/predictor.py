r"""The boundary-increment predictor of :class:`~hyperfem.solver.NewtonSolver`.

When the prescribed boundary values moved since the last solve, one linear
solve with the tangent at the old state and the increment as a lifted
Dirichlet condition carries the increment into the interior, instead of
moving only the boundary nodes and squeezing the first layer of cells
(displacement-driven loading then takes a few steps, not hundreds; see
``tests/test_predictor.py``). A lift whose Krylov solve fails is solved once
more with LU, as a Newton direction is (:meth:`BoundaryPredictor._direct_fallback`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx.la.petsc import _ghost_update

from hyperfem.problem.protocol import SolidProblem
from hyperfem.solver.lag import PreconditionerLag
from hyperfem.solver.linear import LinearSolver
from hyperfem.solver.state import assign_state

__all__ = ["BoundaryPredictor"]

_INDEFINITE_MATRIX = int(PETSc.KSP.ConvergedReason.DIVERGED_INDEFINITE_MAT)

MAX_PREDICTOR_HALVINGS = 8
"""The predicted increment is halved at most this often to keep :math:`J > J_\\min`; then it is dropped."""


class BoundaryPredictor:
    """The predictor of one solver: its problem, assembly and work vectors.

    Args:
        problem: The problem (its unknown and Dirichlet conditions).
        nlp: The solver's ``dolfinx.fem.petsc.NonlinearProblem`` (tangent form and matrix).
        lag: The solver's preconditioner lag (``None``: not lagged). A lift solves with the preconditioner
            as SNES left it; where SNES's last tangent reused an older one (:attr:`PreconditionerLag.reused`)
            and the Krylov solve fails, the lift is solved again with the preconditioner rebuilt, before the
            LU fallback. A preconditioner built on the lift's own tangent goes to the LU fallback at once.
    """

    def __init__(
        self, problem: SolidProblem, nlp: fpetsc.NonlinearProblem, lag: PreconditionerLag | None = None
    ):
        self.problem = problem
        self._nlp = nlp
        self._state = nlp.x.duplicate()
        self._rhs = nlp.b.duplicate()
        self._lag = lag
        self.preconditioner_rebuilds = 0
        """Lifts solved again with the preconditioner rebuilt after a failed Krylov solve (:meth:`_solve`)."""
        self.direct_fallbacks = 0
        """Lifts solved by the LU fallback (:meth:`_direct_fallback`)."""
        self._refused: PETSc.Vec | None = None
        self.refused = False
        """Whether the last lift with ``halve=False`` was solved, applied whole and found inadmissible
        (:meth:`halve_refused` shortens it without solving again)."""

    def moved(self) -> bool:
        """Whether the Dirichlet values differ from the current state anywhere (collective)."""
        u = self.problem.u
        moved = u.x.array.copy()
        for bc in self.problem.bcs:
            bc.set(moved)
        local = not np.array_equal(moved, u.x.array)
        return bool(self.problem.domain.comm.allreduce(local, op=MPI.LOR))

    def lift(
        self,
        ksp: PETSc.KSP,
        *,
        refresh: Callable[[], None],
        preconditioner: Callable[[PETSc.Mat], PETSc.Mat] | None,
        admissible: Callable[[], bool],
        tangent_terms: Callable[[PETSc.Mat], None] | None = None,
        carried: tuple[np.ndarray, np.ndarray] | None = None,
        halve: bool = True,
    ) -> bool:
        r"""Move the state by the tangent response to the boundary increment.

        Solves :math:`K(u_n)\,\delta u = 0` in the interior with
        :math:`\delta u = g_{n+1} - u_n` on the Dirichlet dofs (a lifted
        condition), with the solver's own assembly and linear solver, and
        applies the largest fraction :math:`2^{-k}` of it that keeps the
        state admissible (:math:`J > J_\min`).

        Args:
            ksp: The solver's KSP.
            refresh: The solver's state hooks (run at :math:`u_n` before the assembly).
            preconditioner: ``P(A)``, the preconditioning matrix of a tangent
                ``A`` (``None``: ``A`` itself).
            admissible: Whether the current state of the unknown is admissible (collective).
            tangent_terms: Adds what the tangent form lacks to the assembled
                tangent (the solver's external energies, e.g. a contact barrier).
            carried: More prescribed increments: global dofs (this rank's) and
                values, lifted like the Dirichlet ones (the nodes an obstacle
                pushes, :meth:`~hyperfem.solver.external.ExternalTerms.carry`).
            halve: Shorten an inadmissible step as above; ``False``: apply the whole step and leave the state
                there even if it is inadmissible (the caller looks at it: the nodes a carried lift pushed into
                an obstacle, :meth:`~hyperfem.solver.external.ExternalTerms.carry_more`).

        Returns:
            Whether a step was applied (with ``halve=False``: whether the whole step is admissible).
        """
        self._drop_refused()
        x = self._state
        self.problem.u.x.petsc_vec.copy(x)
        # copy() moves the owned entries only; the lifting below reads x's ghosts too.
        _ghost_update(x, PETSc.InsertMode.INSERT, PETSc.ScatterMode.FORWARD)  # type: ignore[arg-type]  # petsc4py: int enums
        refresh()
        du = x.duplicate()
        keep = False
        try:
            if not self._solve(ksp, x, du, preconditioner, tangent_terms, carried):
                return False
            applied = self._apply(x, du, admissible, MAX_PREDICTOR_HALVINGS if halve else 0)
            if not halve and not applied:
                self._refused, self.refused, keep = du, True, True  # for halve_refused
            return applied
        finally:
            if not keep:
                du.destroy()

    def halve_refused(self, admissible: Callable[[], bool]) -> bool:
        """The last lift refused whole (``halve=False``), applied at the largest admissible ``2^-k``, ``k >= 1``,
        from the state it started at (back there if none is admissible); no new solve. Whether a step was applied."""
        du = self._refused
        if du is None:
            return False
        try:
            return self._apply(self._state, du, admissible, MAX_PREDICTOR_HALVINGS - 1, scale=0.5)
        finally:
            self._drop_refused()

    def _drop_refused(self) -> None:
        if self._refused is not None:
            self._refused.destroy()
        self._refused, self.refused = None, False

    def _solve(
        self,
        ksp: PETSc.KSP,
        x: PETSc.Vec,
        du: PETSc.Vec,
        preconditioner: Callable[[PETSc.Mat], PETSc.Mat] | None,
        tangent_terms: Callable[[PETSc.Mat], None] | None,
        carried: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> bool:
        """The lifted tangent solve for ``du``; whether it converged to a finite increment."""
        nlp = self._nlp
        bcs = self.problem.bcs
        A = nlp.A
        A.zeroEntries()
        fpetsc.assemble_matrix(A, nlp.J, bcs=bcs)  # type: ignore[arg-type, misc]  # dolfinx: singledispatch (Mat, Form)
        A.assemble()
        if tangent_terms is not None:
            tangent_terms(A)
        b = self._rhs
        with b.localForm() as loc:
            loc.set(0.0)
        fpetsc.apply_lifting(b, [nlp.J], bcs=[bcs], x0=[x], alpha=1.0)  # type: ignore[arg-type]  # dolfinx: J is one Form
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]  # petsc4py: int enums
        fpetsc.set_bc(b, bcs, x0=x, alpha=1.0)
        if carried is not None:
            # Lift the carried increments as Dirichlet values: b -= A[:, rows] du_rows, identity rows and columns.
            rows, values = carried
            prescribed = b.duplicate()
            prescribed.set(0.0)
            prescribed.setValues(rows, values)  # type: ignore[arg-type, unused-ignore]  # petsc4py takes arrays
            prescribed.assemble()
            A.zeroRowsColumns(rows, 1.0, prescribed, b)  # type: ignore[arg-type, unused-ignore]  # petsc4py takes arrays
            prescribed.destroy()
        P = None if preconditioner is None else preconditioner(A)
        ksp.setOperators(A, A if P is None else P)
        ksp.solve(b, du)
        reason = int(ksp.getConvergedReason())  # type: ignore[call-overload]  # petsc4py: an int
        if reason <= 0 and self._lag is not None and self._lag.reused and reason != _INDEFINITE_MATRIX:
            # The preconditioner as SNES left it, lagged (built on an older tangent, e.g. before an obstacle's
            # barrier block entered it; the AMG's Chebyshev bounds no longer fit): build it anew on this tangent
            # before any LU, as ``NewtonSolver._recover_direction`` does for a Newton direction.
            pc = ksp.getPC()
            if pc.getType() == PETSc.PC.Type.FIELDSPLIT:
                # A reset would drop the split's index sets (the next solve then fails). Rebuilt on this
                # tangent instead; SNES sets the reuse flag anew at its next tangent.
                pc.setReusePreconditioner(False)
            else:
                # A new hierarchy, aggregates included: rebuilt with its reused interpolation instead, the
                # surgery demo's drag (--n 16) took 16 steps and 69 s, reset 12 steps and 65 s, the steps
                # an unlagged preconditioner takes.
                pc.reset()
                pc.setReusePreconditioner(False)  # a reset keeps the flag: the next lift would reuse this one
            self._lag.rebuilt()
            ksp.setOperators(A, A if P is None else P)
            ksp.solve(b, du)
            self.preconditioner_rebuilds += 1
        if ksp.getConvergedReason() <= 0:  # type: ignore[operator]  # petsc4py: an int
            return self._direct_fallback(A, b, du)
        return bool(np.isfinite(du.norm()))

    def _direct_fallback(self, A: PETSc.Mat, b: PETSc.Vec, du: PETSc.Vec) -> bool:
        """One LU solve of a lift whose Krylov solve failed, as for a Newton direction; whether it gave ``du``.

        An obstacle's barrier block in the tangent stops CG + GAMG (``KSP_DIVERGED_INDEFINITE_PC``); without
        this the lift was dropped, the start stayed refused and the step was cut back (the surgery demo at
        n = 14: 5 steps cut back at their start, the drag in 98 steps instead of 8;
        ``benchmarks/contact_drag_newton.py``). Up to :data:`~hyperfem.solver.newton.DIRECT_FALLBACK_LIMIT`
        unknowns, as ``NewtonSolver._recover_direction``.
        """
        from hyperfem.solver.newton import DIRECT_FALLBACK_LIMIT  # newton imports this module

        if A.getSize()[0] > DIRECT_FALLBACK_LIMIT:
            return False
        reason = LinearSolver().solve(self.problem.domain.comm, A, b, du, kind="fallback")
        self.direct_fallbacks += 1
        return reason > 0 and bool(np.isfinite(du.norm()))

    def _apply(
        self, x: PETSc.Vec, du: PETSc.Vec, admissible: Callable[[], bool], halvings: int, scale: float = 1.0
    ) -> bool:
        """Move the unknown to ``x + scale 2^-k du`` for the smallest admissible ``k < halvings``; back to ``x`` if
        none (``halvings = 0``: to ``x + scale du``, admissible or not)."""
        u = self.problem.u
        if not halvings:
            assign_state(x, u)
            u.x.petsc_vec.axpy(scale, du)
            u.x.scatter_forward()
            return admissible()
        for _ in range(halvings):
            assign_state(x, u)
            u.x.petsc_vec.axpy(scale, du)
            u.x.scatter_forward()
            if admissible():
                return True
            scale *= 0.5
        assign_state(x, u)
        return False
