r"""Unit fibre-direction fields :math:`a_0(X)` in a chosen representation.

Every field is a :class:`dolfinx.fem.Function` of unit vectors in one of

* ``"P1"``  — continuous, vertex values (normalised per vertex),
* ``"DG0"`` — one direction per cell,
* ``"quadrature"`` — values at the quadrature points of the energy (the
  quadrature degree must then equal the problem's).

Zero-length vectors cannot be normalised and raise
:class:`~hyperfem.errors.ParameterError`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from mpi4py import MPI

import basix.ufl
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

from hyperfem.errors import ParameterError, SolverError
from hyperfem.solver.linear import LinearSolver, unique_prefix

if TYPE_CHECKING:
    from dolfinx.fem.petsc import LinearProblem

__all__ = [
    "REPRESENTATIONS",
    "constant_fibres",
    "fibre_space",
    "fibres_from_callable",
    "fibres_from_expression",
    "normalize_fibres",
]

REPRESENTATIONS = ("P1", "DG0", "quadrature")
"""Supported fibre representations."""


def fibre_space(mesh: dmesh.Mesh, representation: str = "DG0", quadrature_degree: int = 1) -> fem.FunctionSpace:
    """The vector function space of a fibre representation.

    Args:
        mesh: DOLFINx mesh.
        representation: ``"P1"``, ``"DG0"`` or ``"quadrature"``.
        quadrature_degree: Degree of the quadrature rule (``"quadrature"`` only).
    """
    gdim = mesh.geometry.dim
    if representation == "P1":
        return fem.functionspace(mesh, ("Lagrange", 1, (gdim,)))
    if representation == "DG0":
        return fem.functionspace(mesh, ("DG", 0, (gdim,)))
    if representation == "quadrature":
        if not (isinstance(quadrature_degree, int) and quadrature_degree >= 0) or isinstance(quadrature_degree, bool):
            raise ParameterError(f"fibre_space: quadrature_degree must be an integer >= 0, got {quadrature_degree!r}")
        element = basix.ufl.quadrature_element(mesh.basix_cell(), value_shape=(gdim,), degree=quadrature_degree)
        return fem.functionspace(mesh, element)
    raise ParameterError(f"unknown fibre representation {representation!r} (available: {', '.join(REPRESENTATIONS)})")


def normalize_fibres(a0: fem.Function, tol: float = 1e-12) -> fem.Function:
    """Normalise a vector function in place, value by value (P1, DG0 or quadrature).

    Raises:
        ParameterError: If some vector has length ``<= tol``.
    """
    bs = a0.function_space.dofmap.index_map_bs
    values = a0.x.array.reshape(-1, bs)
    norms = np.linalg.norm(values, axis=1)
    comm = a0.function_space.mesh.comm
    nonfinite = comm.allreduce(int(np.count_nonzero(~np.isfinite(norms))), op=MPI.SUM)
    if nonfinite:
        raise ParameterError(f"fibre field has {nonfinite} non-finite vector(s) (nan or inf); cannot normalise")
    bad = comm.allreduce(int(np.count_nonzero(norms <= tol)), op=MPI.SUM)
    if bad:
        raise ParameterError(f"fibre field has {bad} zero-length vector(s); cannot normalise")
    values /= norms[:, None]
    a0.x.scatter_forward()
    return a0


def constant_fibres(
    mesh: dmesh.Mesh, direction: Sequence[float], representation: str = "DG0", quadrature_degree: int = 1
) -> fem.Function:
    """A uniform unit fibre field along ``direction`` (normalised)."""
    d = np.asarray(direction, dtype=float)
    if d.shape != (mesh.geometry.dim,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
        raise ParameterError(f"constant_fibres: need a nonzero finite {mesh.geometry.dim}-vector, got {direction!r}")
    return fibres_from_callable(mesh, lambda x: np.outer(d, np.ones(x.shape[1])), representation, quadrature_degree)


def fibres_from_callable(
    mesh: dmesh.Mesh,
    func: Callable[[np.ndarray], np.ndarray],
    representation: str = "DG0",
    quadrature_degree: int = 1,
) -> fem.Function:
    """Fibres from a callable ``func(x) -> (gdim, n)`` of reference coordinates (normalised).

    The callable is evaluated at the representation's points (vertices, cell
    midpoints or quadrature points).
    """
    V = fibre_space(mesh, representation, quadrature_degree)
    a0 = fem.Function(V, name="fibres")
    a0.interpolate(lambda x: np.asarray(func(x), dtype=float))
    return normalize_fibres(a0)


def fibres_from_expression(
    mesh: dmesh.Mesh,
    vector: ufl.core.expr.Expr,
    representation: str = "DG0",
    quadrature_degree: int = 1,
    linear_solver: LinearSolver | None = None,
) -> fem.Function:
    """Fibres from a UFL vector expression (e.g. a gradient), normalised.

    ``"DG0"`` and ``"quadrature"`` interpolate the expression at cell
    midpoints or quadrature points; ``"P1"`` takes its :math:`L^2` projection
    onto continuous P1 (solved with ``linear_solver``, default
    :class:`~hyperfem.solver.linear.LinearSolver`) and normalises the vertex values.
    """
    V = fibre_space(mesh, representation, quadrature_degree)
    a0 = fem.Function(V, name="fibres")
    if representation == "P1":
        _project(vector, a0, linear_solver)
    else:
        a0.interpolate(fem.Expression(vector, V.element.interpolation_points))
    return normalize_fibres(a0)


def _project(expr: ufl.core.expr.Expr, target: fem.Function, linear_solver: LinearSolver | None = None) -> None:
    """:math:`L^2` projection of ``expr`` onto ``target``'s space (one linear-solver configuration, fresh prefix)."""
    from dolfinx.fem.petsc import LinearProblem

    solver = LinearSolver() if linear_solver is None else linear_solver
    V = target.function_space
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    problem = LinearProblem(
        ufl.inner(u, v) * ufl.dx,
        ufl.inner(expr, v) * ufl.dx,
        u=target,
        petsc_options_prefix=unique_prefix("fibre_projection"),
        petsc_options=dict(solver.options),
    )
    problem.solve()
    check_linear_solve(problem, "fibre projection")


def check_linear_solve(problem: LinearProblem, what: str) -> None:
    """Raise :class:`~hyperfem.errors.SolverError` unless the KSP of a DOLFINx ``LinearProblem`` converged."""
    reason = int(problem.solver.getConvergedReason())  # type: ignore[call-overload]  # petsc4py stubs: an int
    if reason <= 0:
        raise SolverError(f"{what}: the linear solve failed (KSP reason {reason})")
