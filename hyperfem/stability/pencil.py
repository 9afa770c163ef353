r"""The tangent of a problem and a metric, assembled as a matrix pencil :math:`(K, B)`.

Stability questions are eigenproblems :math:`K\phi = \lambda B\phi` of the
tangent :math:`K = \partial R/\partial w` at the current state. The metric
:math:`B` is symmetric positive semi-definite and acts on the displacement
only:

* ``"mass"`` (default): the :math:`L^2` mass matrix of the displacement,
  :math:`B = \int_\Omega \delta u\cdot v\,dX` (unit density). The eigenvalues
  are then mesh-independent approximations of those of the continuous
  linearised operator (squared frequencies of a body of unit density), so
  they converge under refinement and can be compared between meshes;
* ``"euclidean"``: the identity on the displacement dofs, the eigenvalues of
  the assembled matrix itself (they scale with the element size).

**Dirichlet conditions** are removed from the spectrum by the pencil, not by
a large diagonal: :math:`K` has its constrained rows and columns zeroed with
1 on the diagonal, :math:`B` has them zeroed with 0 on the diagonal. A
constrained dof is then an *infinite* eigenvalue of the pencil, which
shift-and-invert maps to :math:`1/(\lambda - \sigma) = 0`, the far end of the
transformed spectrum: no value has to be guessed "above the spectrum of
interest" (a diagonal that is too small pollutes the lowest eigenvalues, one
that is too large spoils the conditioning), and the finite eigenvalues are
exactly those of :math:`K` restricted to the free dofs.

**Mixed (u, p, θ) problems.** The three-field tangent is a saddle point
(indefinite by construction: one negative eigenvalue per pressure dof), so
its own eigenvalues say nothing about stability. A state is stable when the
energy *reduced* to the displacement, :math:`\Pi_r(u) = \Pi(u, p(u),
\theta(u))`, has a positive definite Hessian; that Hessian is the Schur
complement :math:`S = K_{uu} - K_{uq}K_{qq}^{-1}K_{qu}` of the constraint
block :math:`q = (p, \theta)`. With :math:`B` zero on the :math:`q` rows, the
finite eigenvalues of :math:`(K, B)` are exactly those of :math:`(S, M_u)`:
:math:`K_{qu}\phi_u + K_{qq}\phi_q = 0` eliminates :math:`\phi_q`. No Schur
complement is formed; shift-and-invert factorises the full tangent. For the
count of negative eigenvalues, Haynsworth's inertia additivity
:math:`\operatorname{In}(K) = \operatorname{In}(K_{qq}) + \operatorname{In}(S)`
gives :math:`n_-(S) = n_-(K) - n_-(K_{qq})`, both from :math:`LDL^T`
factorisations (:meth:`TangentPencil.constraint_negatives`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem

from hyperfem.errors import ParameterError
from hyperfem.problem.protocol import SolidProblem, StateHookedProblem
from hyperfem.solver.constraints import unconstrained_rigid_modes
from hyperfem.solver.inertia import negative_pivots

__all__ = ["METRICS", "TangentPencil", "negative_pivots"]

METRICS = ("mass", "euclidean")
"""Names of the metrics :math:`B` (see the module docstring)."""


class TangentPencil:
    r"""The tangent :math:`K` of a problem and a metric :math:`B` on its displacement (see the module docstring).

    Both matrices share one sparsity pattern (that of the tangent form), so
    :math:`K - \sigma B` is formed without new allocation. The forms are
    compiled once; :meth:`assemble` assembles :math:`K` at the problem's
    current state (after the problem's state hooks).

    Args:
        problem: A :class:`~hyperfem.problem.protocol.SolidProblem` whose
            Dirichlet conditions fix every rigid-body motion.
        metric: ``"mass"``, ``"euclidean"``, or ``None`` (no :attr:`B`: a pencil whose
            right matrix the caller builds, as the buckling analysis does).
        jacobian: The tangent form (default ``problem.jacobian``).
        form_compiler_options: FFCx options of the compiled forms.
        jit_options: JIT options of the compiled forms.
        where: Name used in error messages.

    Attributes:
        K: The tangent matrix (values of the last :meth:`assemble`; assembled on construction).
        tangent_form: The compiled tangent form.
        symmetric: Whether the tangent is symmetric (no follower loads: the Hessian of :math:`\Pi`).
        saddle_point: Whether the unknown has constraint fields besides the displacement.
        displacement_space: The (collapsed) displacement space of the modes.
        displacement_dofs: Local indices into ``problem.u``'s array of each
            dof of :attr:`displacement_space`.

    Raises:
        ParameterError: An unknown metric, Dirichlet conditions that leave a
            rigid-body motion free (the tangent is singular whatever the
            state), or a problem with a displacement subspace that does not
            say where its other fields are.
    """

    def __init__(
        self,
        problem: SolidProblem,
        metric: str | None = "mass",
        *,
        jacobian: ufl.Form | None = None,
        form_compiler_options: dict[str, Any] | None = None,
        jit_options: dict[str, Any] | None = None,
        where: str = "TangentPencil",
    ) -> None:
        if metric is not None and metric not in METRICS:
            raise ParameterError(f"{where}: metric must be one of {', '.join(METRICS)}, got {metric!r}")
        if not problem.rigid_motion_resisted:
            free = unconstrained_rigid_modes(problem)
            if free:
                raise ParameterError(
                    f"{where}: the Dirichlet conditions leave rigid-body motion free ({', '.join(free)}); "
                    "the tangent is singular at every state"
                )
        self.problem = problem
        self.metric = metric
        self.comm: MPI.Comm = problem.domain.comm
        self.symmetric = problem.follower_residual is None
        W = problem.u.function_space
        sub = problem.displacement_space()
        self.saddle_point = sub is not W
        compiler: dict[str, Any] = {"form_compiler_options": form_compiler_options, "jit_options": jit_options}
        self.tangent_form = fem.form(problem.jacobian if jacobian is None else jacobian, **compiler)
        if self.saddle_point:
            self.displacement_space, dofs = sub.collapse()
            self.displacement_dofs = np.asarray(dofs, dtype=np.int64).reshape(-1)
        else:
            self.displacement_space = W
            self.displacement_dofs = np.arange(len(problem.u.x.array), dtype=np.int64)
        self._constraint_is = self._constraint_index_set(where) if self.saddle_point else None
        self._hooks: Sequence[Callable[[], None]] = (
            problem.state_hooks if isinstance(problem, StateHookedProblem) else ()
        )
        self.K = self.assemble(fpetsc.create_matrix(self.tangent_form))
        self._B = self._metric_matrix(compiler)

    # -- construction ------------------------------------------------------
    def _displacement(self, argument: ufl.Argument) -> ufl.core.expr.Expr:
        """The displacement block of a test or trial function of ``u``'s space (the first block)."""
        return ufl.split(argument)[0] if self.saddle_point else argument

    def _free_displacement(self) -> fem.Function:
        """1 on the displacement dofs that no Dirichlet condition fixes, 0 elsewhere."""
        indicator = fem.Function(self.problem.u.function_space)
        indicator.x.array[self.displacement_dofs] = 1.0
        for bc in self.problem.bcs:
            bc.set(indicator.x.array, alpha=0.0)
        indicator.x.scatter_forward()
        return indicator

    def _metric_matrix(self, compiler: dict[str, Any]) -> PETSc.Mat | None:
        """:math:`B` in the pattern of :attr:`K` (assembled once, so that its pattern is complete)."""
        if self.metric is None:
            return None
        B = self.K.duplicate(copy=False)  # zero values, the tangent's pattern: K - sigma B needs no new entries
        if self.metric == "mass":
            W = self.problem.u.function_space
            v, dw = ufl.TestFunction(W), ufl.TrialFunction(W)
            dx = ufl.Measure("dx", domain=W.mesh, metadata={"quadrature_degree": 2 * self.problem.degree})
            mass = fem.form(ufl.inner(self._displacement(dw), self._displacement(v)) * dx, **compiler)
            fpetsc.assemble_matrix(B, mass, bcs=self.problem.bcs, diag=0.0)  # type: ignore[arg-type, misc]  # dolfinx: singledispatch (Mat, Form)
        else:
            free = self._free_displacement()  # held: its PETSc vector wraps the function's array
            B.setDiagonal(free.x.petsc_vec)
        B.assemble()
        return B

    def _constraint_index_set(self, where: str) -> PETSc.IS:
        """Global indices of this rank's owned dofs outside the displacement block (pressure, volume, ...)."""
        W = self.problem.u.function_space
        imap = W.dofmap.index_map
        owned = imap.size_local * W.dofmap.index_map_bs
        constraint = np.ones(len(self.problem.u.x.array), dtype=bool)
        constraint[self.displacement_dofs] = False
        local = np.flatnonzero(constraint[:owned])
        total = self.comm.allreduce(len(local), op=MPI.SUM)
        if total == 0:
            raise ParameterError(f"{where}: the unknown has a displacement subspace but no other field")
        indices = (local + imap.local_range[0] * W.dofmap.index_map_bs).astype(PETSc.IntType)
        return PETSc.IS().createGeneral(indices, comm=self.comm)  # type: ignore[arg-type]  # petsc4py takes arrays

    # -- use ---------------------------------------------------------------
    def refresh(self) -> None:
        """Run the problem's state hooks (what a solver does before assembling at a new state)."""
        for hook in self._hooks:
            hook()

    def assemble(self, K: PETSc.Mat | None = None) -> PETSc.Mat:
        """Assemble the tangent at the current state into ``K`` (default :attr:`K`), Dirichlet rows set to identity.

        Returns:
            The assembled matrix.
        """
        K = self.K if K is None else K
        self.refresh()
        K.zeroEntries()
        fpetsc.assemble_matrix(K, self.tangent_form, bcs=self.problem.bcs, diag=1.0)  # type: ignore[arg-type, misc]  # dolfinx: singledispatch (Mat, Form)
        K.assemble()
        return K

    @property
    def B(self) -> PETSc.Mat:
        """The metric matrix.

        Raises:
            ParameterError: The pencil was built without a metric.
        """
        if self._B is None:
            raise ParameterError("TangentPencil: built with metric=None, it has no metric matrix")
        return self._B

    def new_matrix(self) -> PETSc.Mat:
        """A zero matrix of the tangent's pattern."""
        return self.K.duplicate(copy=False)

    def constraint_negatives(self, K: PETSc.Mat | None = None) -> int:
        r"""Negative eigenvalues of the constraint block :math:`K_{qq}` of a saddle-point tangent (0 otherwise).

        For the three-field problem :math:`K_{qq} = \begin{pmatrix}0 & -M\\ -M & H\end{pmatrix}`
        with the nonsingular :math:`p`–:math:`\theta` mass matrix :math:`M`: one
        negative eigenvalue per pressure dof whatever :math:`H`; it is counted
        (collective), not assumed, so that other saddle-point problems are right too.
        """
        if self._constraint_is is None:
            return 0
        K = self.K if K is None else K
        block = K.createSubMatrix(self._constraint_is, self._constraint_is)
        try:
            return negative_pivots(block)
        finally:
            block.destroy()

    def mode(self, vector: PETSc.Vec, name: str) -> fem.Function:
        """The displacement block of a vector of ``u``'s layout as a function on :attr:`displacement_space`.

        Scaled to a largest nodal displacement of 1, signed so that the
        largest entry (the first on the lowest rank among equals) is positive.
        """
        full = fem.Function(self.problem.u.function_space)
        vector.copy(full.x.petsc_vec)
        full.x.scatter_forward()
        mode = fem.Function(self.displacement_space, name=name)
        mode.x.array[:] = full.x.array[self.displacement_dofs]
        bs = self.displacement_space.dofmap.index_map_bs
        owned = self.displacement_space.dofmap.index_map.size_local * bs
        values = mode.x.array[:owned]
        nodal = np.linalg.norm(values.reshape(-1, bs), axis=1) if values.size else np.zeros(0)
        largest = self.comm.allreduce(float(nodal.max(initial=0.0)), op=MPI.MAX)
        if largest > 0.0:
            k = int(np.argmax(np.abs(values))) if values.size else -1
            local = (float(abs(values[k])), -self.comm.rank, float(np.sign(values[k]))) if k >= 0 else (-1.0, 0, 1.0)
            sign = max(self.comm.allgather(local))[2] or 1.0
            mode.x.array[:] *= sign / largest
        return mode

    def destroy(self) -> None:
        """Free the PETSc objects."""
        self.K.destroy()
        if self._B is not None:
            self._B.destroy()
        if self._constraint_is is not None:
            self._constraint_is.destroy()
