r"""Linearised buckling: critical load factors and modes from the tangent at a reference state.

At an equilibrium :math:`u_0` at load factor :math:`t_0`, the tangent is
assumed to vary linearly with the load factor along the pre-buckling path,

.. math::
    K(t_0 + \mu\,\Delta t) \approx K_0 + \mu\,\Delta K,
    \qquad \Delta K = K(u_1, t_1) - K(u_0, t_0),\quad t_1 = t_0 + \Delta t,

and the path loses stability where this tangent becomes singular:

.. math::
    K_0\,\phi = \mu\,(-\Delta K)\,\phi,\qquad t_\text{cr} = t_0 + \mu\,\Delta t .

The state :math:`u_1` at :math:`t_1` is either

* ``prestress="linear"`` (default; the classical linearised buckling of
  Abaqus ``*BUCKLE``): one tangent solve from :math:`u_0`,
  :math:`K_0(u_1 - u_0) = -R(u_0, t_1)` with the Dirichlet values of
  :math:`t_1`, so :math:`\Delta K` is the change of stiffness of the linear
  pre-buckling response (geometric stiffness of the stress increment,
  load stiffness of follower loads); or
* ``prestress="nonlinear"``: the equilibrium at :math:`t_1`, solved by
  :class:`~hyperfem.solver.NewtonSolver` from :math:`u_0` — :math:`\Delta K`
  is then the secant of the tangent along the true path, and
  :math:`t_\text{cr}` is exact when the critical point lies at :math:`t_1`
  (refine by moving :math:`t_0` and :math:`\Delta t` towards it).

Both are exact to first order in :math:`\Delta t`; they differ by the
non-linearity of the pre-buckling path (for an Euler column, by terms of the
order of the axial strain). Dirichlet dofs are out of the spectrum
(identity rows in :math:`K_0` and :math:`K_1`, so zero rows in :math:`\Delta K`:
infinite :math:`\mu`). The pencil is not symmetric-definite (:math:`\Delta K`
is indefinite, and :math:`K_0` is indefinite for the mixed problem), so it
is solved as a general eigenproblem with shift-and-invert at
:math:`\mu = 0`: the multipliers of smallest magnitude come first, and the
positive ones (the load increasing in the direction of :math:`\Delta t`) are
the critical load factors; negative ones (buckling under the reversed load)
are reported apart. For the mixed problem the constraint block of the
pencil (:math:`p`–:math:`\theta`, whose mass coupling does not change) stays
nonsingular, so its finite eigenvalues are those of the displacement-reduced
pencil (see :mod:`hyperfem.stability.pencil`).

The problem's state and load factor are restored afterwards.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem.petsc as fpetsc
from dolfinx import fem

from hyperfem.errors import ConvergenceError, ParameterError, SolverError
from hyperfem.problem.protocol import SolidProblem
from hyperfem.solver.linear import LinearSolver
from hyperfem.stability.eigensolver import solve_pencil
from hyperfem.stability.pencil import TangentPencil
from hyperfem.validation import check_count, check_positive, is_finite_number

__all__ = ["PRESTRESS", "BucklingResult", "buckling_analysis", "write_buckling_modes"]

PRESTRESS = ("linear", "nonlinear")
"""How the state at :math:`t_0 + \\Delta t` is found (see the module docstring)."""


@dataclass(frozen=True)
class BucklingResult:
    r"""Critical load factors and buckling modes of a linearised buckling analysis.

    Attributes:
        load_factors: Critical load factors :math:`t_0 + \mu\Delta t`, ascending
            (the positive multipliers; at most the number asked for).
        multipliers: The multipliers :math:`\mu` of :attr:`load_factors`.
        reversed_multipliers: Negative multipliers found (buckling under the reversed load increment).
        reference_time: :math:`t_0`.
        increment: :math:`\Delta t`.
        prestress: ``"linear"`` or ``"nonlinear"``.
        converged: Eigenpairs SLEPc converged.
        requested: Critical loads asked for.
        modes: The buckling modes as displacement functions (largest nodal
            displacement 1), in the order of :attr:`load_factors`.
    """

    load_factors: tuple[float, ...]
    multipliers: tuple[float, ...]
    reversed_multipliers: tuple[float, ...]
    reference_time: float
    increment: float
    prestress: str
    converged: int
    requested: int
    modes: tuple[fem.Function, ...] = field(default=(), repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.load_factors) != len(self.multipliers):
            raise ParameterError(
                f"BucklingResult: {len(self.load_factors)} load factors but {len(self.multipliers)} multipliers"
            )
        if self.prestress not in PRESTRESS:
            raise ParameterError(f"BucklingResult: prestress must be one of {', '.join(PRESTRESS)}")

    @property
    def critical_load_factor(self) -> float:
        """The lowest critical load factor (``nan`` when none was found)."""
        return self.load_factors[0] if self.load_factors else float("nan")

    def as_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (without the modes)."""
        return {
            "load_factors": list(self.load_factors),
            "multipliers": list(self.multipliers),
            "reversed_multipliers": list(self.reversed_multipliers),
            "reference_time": self.reference_time,
            "increment": self.increment,
            "prestress": self.prestress,
            "converged": self.converged,
            "requested": self.requested,
        }


def _check(n: object, increment: object, prestress: object, tol: object, solver: object) -> None:
    where = "buckling_analysis"
    check_count("n", n, where)
    if not (is_finite_number(increment) and increment != 0):
        raise ParameterError(f"{where}: increment must be a finite nonzero number, got {increment!r}")
    if prestress not in PRESTRESS:
        raise ParameterError(f"{where}: prestress must be one of {', '.join(PRESTRESS)}, got {prestress!r}")
    check_positive("tol", tol, where)  # type: ignore[arg-type]  # checked to be a number
    if solver is not None and prestress != "nonlinear":
        raise ParameterError(f"{where}: a solver is used with prestress='nonlinear' only")


def _linear_step(pencil: TangentPencil, K0: PETSc.Mat, t1: float) -> None:
    """Move the state by :math:`K_0^{-1}(-R(u_0, t_1))`, the Dirichlet dofs to their values at ``t1``."""
    problem = pencil.problem
    problem.set_time(t1)
    bcs = problem.bcs
    residual = fem.form(problem.residual)
    x = problem.u.x.petsc_vec.copy()
    x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    b = fpetsc.assemble_vector(residual)
    du = b.duplicate()
    try:
        b.scale(-1.0)
        fpetsc.apply_lifting(b, [pencil.tangent_form], bcs=[bcs], x0=[x], alpha=1.0)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)  # type: ignore[arg-type]  # int enums
        fpetsc.set_bc(b, bcs, x0=x, alpha=1.0)
        reason = LinearSolver().solve(pencil.comm, K0, b, du, kind="buckling_prestress")
        if reason <= 0 or not np.isfinite(du.norm()):
            raise SolverError(f"buckling_analysis: the linear pre-buckling solve failed (KSP reason {reason})")
        problem.u.x.petsc_vec.axpy(1.0, du)
        problem.u.x.scatter_forward()
    finally:
        for vec in (x, b, du):
            vec.destroy()


def _nonlinear_step(problem: SolidProblem, solver: Any, t1: float) -> None:
    """Solve the equilibrium at ``t1`` from the current state with ``solver`` (a NewtonSolver, made if ``None``)."""
    from hyperfem.solver.newton import NewtonSolver

    if solver is None:
        solver = NewtonSolver(problem)
    elif not isinstance(solver, NewtonSolver) or solver.problem is not problem:
        raise ParameterError("buckling_analysis: solver must be a NewtonSolver of the same problem")
    problem.set_time(t1)
    record = solver.solve()
    if not record.converged:
        raise ConvergenceError(
            f"buckling_analysis: no equilibrium at t = {t1:g} for the prestress ({record.reason_name}); "
            "use a smaller increment or prestress='linear'",
            time=problem.time,
        )


def buckling_analysis(
    problem: SolidProblem,
    n: int = 2,
    *,
    increment: float = 1.0,
    prestress: str = "linear",
    solver: Any = None,
    tol: float = 1e-10,
) -> BucklingResult:
    r"""Critical load factors :math:`t_\text{cr} = t_0 + \mu\,\Delta t` and modes at the problem's current state.

    The current state (``problem.u`` at ``problem.time``) is the reference
    :math:`(u_0, t_0)`; it should be an equilibrium, and is restored
    afterwards. See the module docstring for the formulation.

    Args:
        problem: A displacement or mixed problem whose Dirichlet conditions fix every rigid motion.
        n: Number of critical load factors (and modes) wanted.
        increment: :math:`\Delta t` (the load factor of the reference load
            when :math:`t_0 = 0` and the loads are linear in :math:`t`).
        prestress: ``"linear"`` or ``"nonlinear"``.
        solver: A :class:`~hyperfem.solver.NewtonSolver` of ``problem`` for
            ``prestress="nonlinear"`` (default: one with default options).
        tol: Relative residual tolerance of the eigenpairs.

    Returns:
        The :class:`BucklingResult`.

    Raises:
        ParameterError: ``n`` < 1, a zero or non-finite increment, an unknown
            ``prestress``, a bad ``tol`` or ``solver``, or Dirichlet conditions
            that leave a rigid-body motion free.
        ConvergenceError: ``prestress="nonlinear"`` and Newton did not
            converge at :math:`t_0 + \Delta t`.
        SolverError: A linear or eigenvalue solve failed.
    """
    _check(n, increment, prestress, tol, solver)
    pencil = TangentPencil(problem, None, where="buckling_analysis")
    t0 = float(problem.time)
    u0 = problem.u.x.array.copy()
    K0 = pencil.K  # assembled at (u0, t0) by the pencil
    K1 = pencil.new_matrix()
    try:
        if prestress == "linear":
            _linear_step(pencil, K0, t0 + increment)
        else:
            _nonlinear_step(problem, solver, t0 + increment)
        pencil.assemble(K1)
        K1.axpy(-1.0, K0, structure=PETSc.Mat.Structure.SAME_NONZERO_PATTERN)  # type: ignore[arg-type]  # int enums
        K1.scale(-1.0)  # B = -(K1 - K0)
        pairs = solve_pencil(K0, K1, n, symmetric=False, tol=tol, kind="buckling")
    finally:
        problem.u.x.array[:] = u0
        problem.set_time(t0)
        pencil.refresh()  # state hooks at u0 again
        K1.destroy()
    try:
        mu = np.array([v.real for v in pairs.values])
        positive = np.flatnonzero(mu > 0.0)
        positive = positive[np.argsort(mu[positive], kind="stable")][:n]
        modes = tuple(pencil.mode(pairs.vectors[int(i)], f"buckling_mode_{k}") for k, i in enumerate(positive))
    finally:
        pairs.destroy()
        pencil.destroy()
    return BucklingResult(
        load_factors=tuple(float(t0 + m * increment) for m in mu[positive]),
        multipliers=tuple(float(m) for m in mu[positive]),
        reversed_multipliers=tuple(sorted(float(m) for m in mu if m < 0.0)),
        reference_time=t0,
        increment=float(increment),
        prestress=prestress,
        converged=pairs.converged,
        requested=int(n),
        modes=modes,
    )


def write_buckling_modes(result: BucklingResult, path: str | Path, comm: MPI.Comm | None = None) -> Path:
    """Write the buckling modes to a VTX (``.bp``) folder for ParaView, one frame per mode.

    Frame :math:`k` (its "time" is :math:`k`) holds mode :math:`k`, named
    ``buckling_mode``; warp by it to see the shape.

    Args:
        result: A :class:`BucklingResult` with modes.
        path: Output ``.bp`` folder.
        comm: Communicator (default: the modes' mesh communicator).

    Returns:
        The path written.

    Raises:
        ParameterError: The result has no modes.
        OutputError: The file cannot be written.
    """
    from hyperfem.io.results import VTXWriter

    if not result.modes:
        raise ParameterError("write_buckling_modes: the result has no modes")
    first = result.modes[0]
    comm = first.function_space.mesh.comm if comm is None else comm
    frame = fem.Function(first.function_space, name="buckling_mode")
    modes: Sequence[fem.Function] = result.modes
    with VTXWriter(comm, path, [frame]) as writer:
        for k, mode in enumerate(modes):
            frame.x.array[:] = mode.x.array
            writer.write(float(k))
    return Path(path)
