r"""Polar decomposition with the rotation-variant SVD, and tensor fields at quadrature points.

Rotation-variant SVD (seed 004, Algorithm 6). A standard SVD
:math:`F = U\Sigma V^T` has :math:`\sigma_1 \ge \dots \ge \sigma_d \ge 0`
but :math:`U, V` may be reflections. Flipping the last column of a
reflection together with the sign of :math:`\sigma_d`,

.. math::
    \det U < 0:\ U_{:,d} \leftarrow -U_{:,d},\ \sigma_d \leftarrow -\sigma_d;\qquad
    \det V < 0:\ V_{:,d} \leftarrow -V_{:,d},\ \sigma_d \leftarrow -\sigma_d,

gives :math:`U, V \in SO(d)` and :math:`\operatorname{sign}\sigma_d = \operatorname{sign}\det F`:
an inverted element keeps a proper rotation and its smallest singular value
takes the sign. The polar decomposition is then

.. math::
    F = R\,S,\qquad R = U V^T\ (\det R = +1),\qquad S = V \Sigma V^T = S^T,

and :math:`R` is the rotation closest to :math:`F` in the Frobenius norm
(:math:`S` is indefinite when :math:`\det F < 0`). Its derivative
(:func:`rotation_derivative`) follows from differentiating the SVD:
with :math:`M = U^T\,\delta F\,V`,

.. math::
    \delta R = U\,K\,V^T,\qquad K_{ij} = \frac{M_{ij} - M_{ji}}{\sigma_i + \sigma_j}\ (i \ne j),\quad K_{ii} = 0.

Everything is vectorised over stacks of shape ``(n, d, d)``, ``d`` = 2 or 3.

:class:`QuadratureField` is a tensor-valued :class:`dolfinx.fem.Function` on a
quadrature element of a given degree: the way to hold, in a UFL form, a
quantity computed in NumPy per quadrature point (a polar rotation, a tangent
modulus). :meth:`QuadratureField.evaluate` evaluates a UFL expression such as
:math:`F` at the points of the field with :class:`dolfinx.fem.Expression` and
returns ``(n, *shape)`` values in the order :meth:`QuadratureField.assign`
takes them.
"""

from __future__ import annotations

import basix
import basix.ufl
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh

from hyperfem.errors import ParameterError

__all__ = [
    "QuadratureField",
    "RotationField",
    "polar_decomposition",
    "polar_rotation",
    "polar_svd",
    "rotation_derivative",
]

_DENOMINATOR_FLOOR = 1e-12
"""Relative floor of :math:`\\sigma_i + \\sigma_j` in :func:`rotation_derivative` (a degenerate inverted state)."""


def _as_stack(F: np.ndarray, where: str) -> np.ndarray:
    F = np.asarray(F, dtype=float)
    if F.ndim < 2 or F.shape[-1] != F.shape[-2] or F.shape[-1] not in (2, 3):
        raise ParameterError(f"{where}: need an array of 2x2 or 3x3 matrices (..., d, d), got shape {F.shape}")
    return F


def polar_svd(F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r"""Rotation-variant SVD :math:`F = U \operatorname{diag}(\sigma) V^T` with :math:`U, V \in SO(d)`.

    Seed 004, Algorithm 6: a reflection in :math:`U` or :math:`V` is turned
    into a rotation by flipping its last column and the sign of
    :math:`\sigma_d`.

    Args:
        F: Matrices of shape ``(..., d, d)``.

    Returns:
        ``(U, sigma, V)`` of shapes ``(..., d, d)``, ``(..., d)``, ``(..., d, d)``
        (``V``, not ``V^T``); :math:`\sigma_1 \ge \dots \ge \sigma_{d-1} \ge |\sigma_d|`
        and :math:`\operatorname{sign} \sigma_d = \operatorname{sign} \det F`.
    """
    F = _as_stack(F, "polar_svd")
    U, sigma, Vt = np.linalg.svd(F)
    V = np.swapaxes(Vt, -1, -2).copy()
    for Q in (U, V):
        flip = np.linalg.det(Q) < 0
        Q[flip, :, -1] *= -1.0
        sigma[flip, -1] *= -1.0
    return U, sigma, V


def polar_decomposition(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""Polar decomposition :math:`F = R S`, :math:`\det R = +1`, :math:`S` symmetric.

    Args:
        F: Matrices of shape ``(..., d, d)``.

    Returns:
        ``(R, S)``, both of the shape of ``F``. For an inverted ``F``
        (:math:`\det F < 0`) :math:`S` has one negative eigenvalue.
    """
    U, sigma, V = polar_svd(F)
    R = U @ np.swapaxes(V, -1, -2)
    S = (V * sigma[..., None, :]) @ np.swapaxes(V, -1, -2)
    return R, 0.5 * (S + np.swapaxes(S, -1, -2))


def polar_rotation(F: np.ndarray) -> np.ndarray:
    """The rotation :math:`R` of :func:`polar_decomposition` (the proper rotation closest to ``F``)."""
    U, _, V = polar_svd(F)
    return U @ np.swapaxes(V, -1, -2)


def rotation_derivative(U: np.ndarray, sigma: np.ndarray, V: np.ndarray) -> np.ndarray:
    r"""Derivative :math:`T_{ijkl} = \partial R_{ij} / \partial F_{kl}` of the polar rotation.

    From the rotation-variant SVD (:func:`polar_svd`): :math:`\delta R = U K V^T`
    with :math:`K_{ij} = (M_{ij} - M_{ji})/(\sigma_i + \sigma_j)`,
    :math:`M = U^T \delta F V` (module docstring). :math:`T` is symmetric
    under :math:`(ij) \leftrightarrow (kl)` and maps every symmetric
    :math:`\delta S` in :math:`\delta F = R\,\delta S` to zero. Where
    :math:`\sigma_i + \sigma_j` vanishes (a degenerate inverted state, where
    :math:`R` is not differentiable) the denominator is floored at
    :data:`_DENOMINATOR_FLOOR` times :math:`\max(1, \sigma_1)`.

    Args:
        U, sigma, V: Output of :func:`polar_svd`, leading shape ``(n,)``.

    Returns:
        Array of shape ``(n, d, d, d, d)``.
    """
    U = np.asarray(U, dtype=float)
    V = np.asarray(V, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    d = sigma.shape[-1]
    floor = _DENOMINATOR_FLOOR * np.maximum(1.0, np.abs(sigma[..., :1]))[..., None]
    denom = np.maximum(sigma[..., :, None] + sigma[..., None, :], floor)
    inv = 1.0 / denom
    inv[..., np.arange(d), np.arange(d)] = 0.0
    # dR_ab = sum_ij U_ai V_bj inv_ij (M_ij - M_ji), M_ij = U_ki dF_kl V_lj.
    # Basis of the (ij) skew modes: E_ab^(ij) = U_ai V_bj - U_aj V_bi.
    E = np.einsum("...ai,...bj->...abij", U, V)
    E = E - np.swapaxes(E, -1, -2)
    # T_abkl = sum_{i<j} inv_ij E_ab^(ij) E_kl^(ij)  (each unordered pair once: M_ij - M_ji = E^(ij) : dF),
    # i.e. half the sum over ordered pairs: a batched E diag(inv/2) E^T over the flattened (ab), (ij).
    lead = sigma.shape[:-1]
    E = E.reshape(*lead, d * d, d * d)
    half = 0.5 * inv.reshape(*lead, 1, d * d)
    T = (E * half) @ np.swapaxes(E, -1, -2)
    return T.reshape(*lead, d, d, d, d)


class QuadratureField:
    r"""A tensor-valued function on the quadrature element of degree ``degree`` (or cellwise constant).

    Use :attr:`function` in UFL forms integrated with the same rule
    (``metadata={"quadrature_degree": degree}``, default scheme); FFCx
    refuses a quadrature element on a different rule. With
    ``cellwise_constant`` the field is a DG0 tensor function instead, one
    value per cell taken at the cell's centroid: exact for quantities of a
    cellwise-constant :math:`F` (P1 on affine simplices) and usable with any
    rule. The values cover every local cell, ghosts included, so no scatter
    is needed after :meth:`assign`.

    Args:
        mesh: The mesh.
        degree: Quadrature degree (points of ``basix.make_quadrature``, default scheme).
        shape: Value shape, e.g. ``(3, 3)``.
        name: Name of the function.
        cellwise_constant: One value per cell (DG0) instead of one per quadrature point.

    Attributes:
        function: The :class:`dolfinx.fem.Function`.
        points: Reference points of the values, shape ``(num_points, tdim)``.
        num_cells: Local cells (owned and ghost) the values cover.
    """

    def __init__(
        self,
        mesh: dmesh.Mesh,
        degree: int,
        shape: tuple[int, ...],
        name: str = "quadrature_field",
        cellwise_constant: bool = False,
    ):
        cell = mesh.basix_cell()
        self.mesh = mesh
        self.degree = int(degree)
        self.shape = tuple(shape)
        self.cellwise_constant = bool(cellwise_constant)
        if self.cellwise_constant:
            self.space = fem.functionspace(mesh, ("DG", 0, self.shape))
            self.points = np.mean(basix.geometry(cell), axis=0, keepdims=True)
        else:
            element = basix.ufl.quadrature_element(cell, value_shape=self.shape, degree=self.degree)
            self.space = fem.functionspace(mesh, element)
            self.points, _ = basix.make_quadrature(cell, self.degree)  # type: ignore[assignment, unused-ignore]  # basix: ndarrays (stubs differ between the wheel and Debian)
        self.function = fem.Function(self.space, name=name)
        tdim = mesh.topology.dim
        imap = mesh.topology.index_map(tdim)
        self.num_cells = imap.size_local + imap.num_ghosts
        self._cells = np.arange(self.num_cells, dtype=np.int32)
        self._dofs = self.space.dofmap.list[: self.num_cells].reshape(-1)
        self._block = int(np.prod(self.shape)) if self.shape else 1

    @property
    def num_points(self) -> int:
        """Quadrature points per cell."""
        return self.points.shape[0]

    def expression(self, expr: ufl.core.expr.Expr, jit_options: dict | None = None) -> fem.Expression:
        """Compile ``expr`` (no arguments) at the points of this field."""
        return fem.Expression(expr, self.points, jit_options=jit_options)

    def evaluate(self, expression: fem.Expression | ufl.core.expr.Expr) -> np.ndarray:
        """Values of ``expression`` at every point of every local cell, shape ``(n, *expr_shape)``.

        ``n = num_cells * num_points``, cell by cell (the order of :meth:`assign`).
        """
        if not isinstance(expression, fem.Expression):
            expression = self.expression(expression)
        values = expression.eval(self.mesh, self._cells)
        return values.reshape(self.num_cells * self.num_points, *values.shape[2:])

    def assign(self, values: np.ndarray) -> None:
        """Set the field from ``values`` of shape ``(num_cells * num_points, *shape)``."""
        values = np.asarray(values, dtype=self.function.x.array.dtype)
        expected = (self.num_cells * self.num_points, *self.shape)
        if values.shape != expected:
            raise ParameterError(f"QuadratureField.assign: need values of shape {expected}, got {values.shape}")
        self.function.x.array.reshape(-1, self._block)[self._dofs] = values.reshape(-1, self._block)

    def values(self) -> np.ndarray:
        """The field as an array of shape ``(num_cells * num_points, *shape)`` (order of :meth:`assign`)."""
        return self.function.x.array.reshape(-1, self._block)[self._dofs].reshape(-1, *self.shape)


def _state_function(F: ufl.core.expr.Expr, where: str) -> fem.Function:
    """The DOLFINx function that ``F`` depends on (the displacement, or a mixed state)."""
    from ufl.algorithms import extract_coefficients

    functions = [c for c in extract_coefficients(F) if isinstance(c, fem.Function)]
    if not functions:
        raise ParameterError(
            f"{where}: needs the deformation gradient of a DOLFINx Function (a problem's F = I + grad u), "
            "got a symbolic F"
        )
    return functions[0]


def _is_cellwise_constant(F: ufl.core.expr.Expr, mesh: dmesh.Mesh) -> bool:
    """Whether ``F`` is constant in each cell: polynomial degree 0 on an affine simplex mesh (P1)."""
    from ufl.algorithms import estimate_total_polynomial_degree
    from ufl.algorithms.apply_algebra_lowering import apply_algebra_lowering

    simplex = mesh.topology.cell_type in (dmesh.CellType.triangle, dmesh.CellType.tetrahedron)
    affine = mesh.geometry.cmaps[0].degree == 1
    return simplex and affine and estimate_total_polynomial_degree(apply_algebra_lowering(F)) == 0


class RotationField:
    r"""The polar rotation :math:`R(F)` (and optionally :math:`\partial R/\partial F`) at quadrature points.

    :math:`R` is not a UFL expression of :math:`F`; it is held in a
    :class:`QuadratureField` and recomputed in NumPy (:func:`polar_svd`) from
    the current :math:`F` by :meth:`refresh`. The field binds to the
    deformation gradient it is first given (:meth:`bind`): the mesh comes
    from the function that :math:`F` depends on, the points from the
    quadrature degree. When :math:`F` is constant in each cell (P1 on an
    affine simplex mesh) the fields are DG0 (one value per cell), which any
    quadrature rule may integrate.

    Args:
        derivative: Also hold :math:`T = \partial R/\partial F` (shape ``(d, d, d, d)``).
        name: Prefix of the field names, for messages.

    Attributes:
        rotation: :class:`QuadratureField` of :math:`R` (``None`` until bound).
        derivative: :class:`QuadratureField` of :math:`T` (``None`` unless requested and bound).
        refreshes: How many times :meth:`refresh` recomputed the fields (a call at an
            unchanged state is skipped).
    """

    def __init__(self, derivative: bool = False, name: str = "RotationField"):
        self.with_derivative = bool(derivative)
        self.name = name
        self.rotation: QuadratureField | None = None
        self.derivative: QuadratureField | None = None
        self.F: ufl.core.expr.Expr | None = None
        self.quadrature_degree: int | None = None
        self.refreshes = 0
        self._F_expression: fem.Expression | None = None
        self._functions: list[fem.Function] = []
        self._last_state: list[np.ndarray] | None = None

    @property
    def bound(self) -> bool:
        """Whether :meth:`bind` has run."""
        return self.F is not None

    @property
    def rule_degree(self) -> int | None:
        """Degree of the rule that forms using the fields must be integrated with.

        ``None``: any rule (unbound, or cellwise-constant fields of a P1 :math:`F`).
        """
        if self.rotation is None or self.rotation.cellwise_constant:
            return None
        return self.quadrature_degree

    def bind(self, F: ufl.core.expr.Expr, quadrature_degree: int | None = None) -> None:
        """Attach to the deformation gradient ``F`` on the rule of degree ``quadrature_degree``.

        Binding again to the same ``F`` (and degree) is a no-op. The default
        degree is that of :class:`~hyperfem.problem.HyperelasticProblem` for
        the degree of the function ``F`` depends on and the mesh's cell type
        (1 for P1 simplices, ``2 p`` otherwise, Q1 hexahedra included).

        Raises:
            ParameterError: ``F`` is symbolic (no DOLFINx function), not a
                2×2/3×3 tensor, or differs from the ``F`` or degree bound before
                (one material object per problem).
        """
        where = self.name
        if isinstance(F, ufl.classes.Variable):  # ufl.variable(F), as a stress measure builds it: F itself
            F = F.ufl_operands[0]
        shape = F.ufl_shape
        if len(shape) != 2 or shape[0] != shape[1] or shape[0] not in (2, 3):
            raise ParameterError(f"{where}: F must be a 2x2 or 3x3 tensor, got shape {shape}")
        if self.F is not None:
            if not F == self.F:
                raise ParameterError(
                    f"{where}: already bound to the deformation gradient of another problem; "
                    "create one material object per problem"
                )
            if quadrature_degree is not None and quadrature_degree != self.quadrature_degree:
                raise ParameterError(
                    f"{where}: bound on quadrature degree {self.quadrature_degree}, asked for {quadrature_degree}"
                )
            return
        u = _state_function(F, where)
        from ufl.algorithms import extract_coefficients
        from ufl.algorithms.analysis import extract_constants

        coefficients = extract_coefficients(F)
        # Skipping an unchanged state is safe only when F depends on nothing but DOLFINx functions.
        only_functions = all(isinstance(c, fem.Function) for c in coefficients) and not extract_constants(F)
        self._functions = list(coefficients) if only_functions else []
        d = shape[0]
        mesh = u.function_space.mesh
        if quadrature_degree is None:
            from hyperfem.problem.quadrature import volume_quadrature_degree

            p = u.function_space.ufl_element().embedded_superdegree
            quadrature_degree = volume_quadrature_degree(p, mesh.topology.cell_type)
        cellwise = _is_cellwise_constant(F, mesh)
        self.rotation = QuadratureField(
            mesh, quadrature_degree, (d, d), name=f"{where}_rotation", cellwise_constant=cellwise
        )
        if self.with_derivative:
            self.derivative = QuadratureField(
                mesh, quadrature_degree, (d, d, d, d), name=f"{where}_dR_dF", cellwise_constant=cellwise
            )
        self.F = F
        self.quadrature_degree = int(quadrature_degree)
        self._F_expression = self.rotation.expression(F)
        self.refresh()

    def refresh(self, force: bool = False) -> None:
        """Recompute the fields from the current value of ``F`` (local cells, ghosts included).

        Skipped when the functions ``F`` depends on have not changed since the
        last recomputation (the solver asks before the residual and again
        before the tangent at the same state), unless ``force``.
        """
        if self.rotation is None or self._F_expression is None:  # bind sets both
            raise ParameterError(f"{self.name}: refresh before the material was bound to a deformation gradient")
        if self._functions:
            state = [f.x.array for f in self._functions]
            if (
                not force
                and self._last_state is not None
                and all(np.array_equal(a, b) for a, b in zip(state, self._last_state, strict=True))
            ):
                return
            self._last_state = [a.copy() for a in state]
        Fq = self.rotation.evaluate(self._F_expression)
        U, sigma, V = polar_svd(Fq)
        self.rotation.assign(U @ np.swapaxes(V, -1, -2))
        if self.derivative is not None:
            self.derivative.assign(rotation_derivative(U, sigma, V))
        self.refreshes += 1

    def deformation_gradients(self) -> np.ndarray:
        """The current :math:`F` at the points, shape ``(n, d, d)`` (order of :meth:`QuadratureField.assign`)."""
        if self.rotation is None or self._F_expression is None:  # bind sets both
            raise ParameterError(f"{self.name}: not bound to a deformation gradient")
        return self.rotation.evaluate(self._F_expression)
