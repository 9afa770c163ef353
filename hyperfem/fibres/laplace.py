r"""Rule-based fibres from a Laplace problem between two named surfaces.

Solve

.. math::
    -\Delta\phi = 0 \ \text{in}\ \Omega,\qquad \phi = 0 \ \text{on}\ \Gamma_\text{source},\qquad
    \phi = 1 \ \text{on}\ \Gamma_\text{target},\qquad \nabla\phi\cdot N = 0 \ \text{elsewhere},

and take :math:`a_0 = \nabla\phi / |\nabla\phi|`: fibres run from the source
surface (e.g. a muscle's ``origin``) to the target (``insertion``) and follow
the shape in between, as rule-based fibre methods do.
"""

from __future__ import annotations

import ufl
from dolfinx import fem

from hyperfem.fibres.fields import check_linear_solve, fibres_from_expression
from hyperfem.mesh.domain import Domain
from hyperfem.solver.linear import LinearSolver, unique_prefix

__all__ = ["laplace_fibres", "laplace_potential"]


def laplace_potential(
    domain: Domain, source: str, target: str, degree: int = 2, linear_solver: LinearSolver | None = None
) -> fem.Function:
    r"""The potential :math:`\phi` with :math:`\phi = 0` on ``source`` and 1 on ``target``.

    Args:
        domain: Mesh with named boundaries.
        source: Boundary name where :math:`\phi = 0`.
        target: Boundary name where :math:`\phi = 1`.
        degree: Lagrange degree of :math:`\phi`.
        linear_solver: Linear-solver configuration (default
            :class:`~hyperfem.solver.linear.LinearSolver`, MUMPS LU).
    """
    from dolfinx.fem.petsc import LinearProblem

    solver = LinearSolver() if linear_solver is None else linear_solver

    mesh = domain.mesh
    fdim = domain.tdim - 1
    V = fem.functionspace(mesh, ("Lagrange", degree))
    bcs = []
    for name, value in ((source, 0.0), (target, 1.0)):
        dofs = fem.locate_dofs_topological(V, fdim, domain.facets(name))
        bcs.append(fem.dirichletbc(value, dofs, V))
    phi, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    zero = fem.Constant(mesh, 0.0)
    solution = fem.Function(V, name="laplace_potential")
    problem = LinearProblem(
        ufl.inner(ufl.grad(phi), ufl.grad(v)) * ufl.dx,
        zero * v * ufl.dx,
        u=solution,
        bcs=bcs,
        petsc_options_prefix=unique_prefix("laplace"),
        petsc_options=dict(solver.options),
    )
    problem.solve()
    check_linear_solve(problem, f"laplace_potential from {source!r} to {target!r}")
    solution.x.scatter_forward()
    return solution


def laplace_fibres(
    domain: Domain,
    source: str,
    target: str,
    representation: str = "DG0",
    quadrature_degree: int = 1,
    degree: int = 2,
    linear_solver: LinearSolver | None = None,
) -> fem.Function:
    """Unit fibres :math:`\\nabla\\phi/|\\nabla\\phi|` of :func:`laplace_potential`.

    Args:
        domain: Mesh with named boundaries.
        source, target: Boundary names (fibres point from source to target).
        representation: ``"P1"``, ``"DG0"`` or ``"quadrature"``.
        quadrature_degree: For the quadrature representation.
        degree: Lagrange degree of the potential.
        linear_solver: Linear-solver configuration of the Laplace solve (and
            of the projection for ``"P1"``).
    """
    phi = laplace_potential(domain, source, target, degree, linear_solver)
    return fibres_from_expression(domain.mesh, ufl.grad(phi), representation, quadrature_degree, linear_solver)
