r"""Exact inversion-free step filtering for P1 simplices (seed 004, "Inversion-Free Line Search Filtering").

For piecewise-linear displacements on straight simplices the deformation
gradient is constant per cell, and the signed volume of a cell along a
Newton direction :math:`p` is a polynomial in the step length :math:`\alpha`.
With :math:`D` the deformed edge vectors :math:`x_i - x_0` (rows) of a cell
at the current state and :math:`P` those of the direction,

.. math::
    \frac{\det(D + \alpha P)}{\det D} = 1 + b\,\alpha + c\,\alpha^2 + d\,\alpha^3

(:math:`d = 0` for triangles), where :math:`b, c, d` are sums of mixed
determinants (:func:`volume_ratio_coefficients`). The largest admissible step
is the smallest positive :math:`\alpha` at which a cell's volume has shrunk to
a fraction :math:`\eta` of its current value,

.. math::
    g(\alpha) = (1 - \eta) + b\,\alpha + c\,\alpha^2 + d\,\alpha^3 = 0,

capped at 1, minimised over the cells and over the ranks. Seed 004 takes
:math:`\eta = 0.1` ("brings the new volume to 0.1x the old volume for
slackness"), :data:`DEFAULT_VOLUME_FRACTION`. Since :math:`g > 0` on
:math:`[0, \alpha^*)`, every shorter step keeps every cell's volume above
:math:`\eta` times its current one — in particular no cell inverts, and a
backtracking line search on :math:`[0, \alpha^*]` never leaves the
admissible set.

The root search (:func:`first_volume_crossing`) uses no cubic formula (its
cancellation for nearly degenerate leading coefficients is what makes the
closed forms fragile) and no per-cell ``np.roots``: the critical points of
:math:`g` (roots of the quadratic :math:`g'`, in a cancellation-free form)
split :math:`[0, 1]` into at most three intervals on which :math:`g` is
monotone; the first interval whose right end has :math:`g \le 0` brackets
the smallest root, which vectorized bisection then pins to machine
precision. A vanishing leading coefficient (:math:`d = 0`, triangles,
:math:`c = d = 0`) needs no special case, and the returned step is the left
end of the final bracket, where :math:`g > 0` was evaluated, so it never
overshoots. :meth:`StepFilter.max_step` also checks the volume ratios at the
returned step directly from the determinants.

Quadrilaterals and hexahedra are refused (:func:`exact_filter_applies` is
``False``): :math:`F` of :math:`Q_1` varies inside the cell, so a cell's volume
ratio does not bound :math:`J` at its points; there
:class:`~hyperfem.solver.NewtonSolver` guards by bisection on the minimum
:math:`J` over the Gauss points of the volume rule.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from hyperfem.errors import ParameterError

__all__ = [
    "DEFAULT_VOLUME_FRACTION",
    "StepFilter",
    "exact_filter_applies",
    "first_volume_crossing",
    "max_step_fractions",
    "volume_ratio_coefficients",
]

DEFAULT_VOLUME_FRACTION = 0.1
r"""Default :math:`\eta`: a step may shrink a cell to no less than this fraction of its current volume (seed 004)."""

BISECTION_STEPS = 60
"""Bisection steps of the root bracket (the bracket starts at most 1 long: 2**-60 is below round-off)."""

_SIMPLICES = (dmesh.CellType.triangle, dmesh.CellType.tetrahedron)


# Internally edge arrays are component-major, shape (d, d, n): E[i] is edge i
# as a (d, n) array, E[i][k] its k-th component over the cells (contiguous,
# which makes the explicit determinant formulas below fast).


def _triple(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """:math:`a \\cdot (b \\times c)` of component-major ``(3, n)`` vectors."""
    return a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) + a[2] * (b[0] * c[1] - b[1] * c[0])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:math:`a \\times b` of component-major ``(3, n)`` vectors."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:math:`a \\cdot b` of component-major ``(3, n)`` vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _det2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:math:`a_0 b_1 - a_1 b_0` of component-major ``(2, n)`` vectors."""
    return a[0] * b[1] - a[1] * b[0]


def _det(E: np.ndarray) -> np.ndarray:
    """Determinants of component-major ``(d, d, n)`` edge arrays (explicit: batched LAPACK is slower)."""
    return _det2(E[0], E[1]) if E.shape[0] == 2 else _triple(E[0], E[1], E[2])


def _coefficients(D: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`volume_ratio_coefficients` of component-major ``(d, d, n)`` arrays."""
    if D.shape[0] == 2:
        (x1, x2), (p1, p2) = D, P
        a0 = _det2(x1, x2)
        return a0, _det2(p1, x2) + _det2(x1, p2), _det2(p1, p2), np.zeros_like(a0)
    (x1, x2, x3), (p1, p2, p3) = D, P
    # Cofactor rows: a1 = sum_i p_i . C_i (one row of P), a2 = sum_i x_i . Q_i (two rows of P).
    C = (_cross(x2, x3), _cross(x3, x1), _cross(x1, x2))
    Q = (_cross(p2, p3), _cross(p3, p1), _cross(p1, p2))
    a0 = _dot(x1, C[0])
    a1 = _dot(p1, C[0]) + _dot(p2, C[1]) + _dot(p3, C[2])
    a2 = _dot(x1, Q[0]) + _dot(x2, Q[1]) + _dot(x3, Q[2])
    a3 = _dot(p1, Q[0])
    return a0, a1, a2, a3


def _component_major(D: np.ndarray, P: np.ndarray, where: str) -> tuple[np.ndarray, np.ndarray]:
    D = np.asarray(D, dtype=float)
    P = np.asarray(P, dtype=float)
    if D.shape != P.shape or D.ndim != 3 or D.shape[1] != D.shape[2] or D.shape[1] not in (2, 3):
        raise ParameterError(
            f"{where}: need edge arrays of equal shape (n, d, d), d = 2 or 3, got {D.shape} and {P.shape}"
        )
    return np.ascontiguousarray(D.transpose(1, 2, 0)), np.ascontiguousarray(P.transpose(1, 2, 0))


def volume_ratio_coefficients(D: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r"""Coefficients of :math:`\det(D + \alpha P) = a_0 + a_1\alpha + a_2\alpha^2 + a_3\alpha^3` per cell.

    By multilinearity of the determinant in the rows: :math:`a_0 = \det D`,
    :math:`a_3 = \det P`, :math:`a_1` the sum of the determinants with one row
    of :math:`D` replaced by the row of :math:`P`, :math:`a_2` with two rows
    replaced. In 2D :math:`a_3 = 0`.

    Args:
        D: Edge vectors at the current state, shape ``(n, d, d)`` (row ``i``:
            :math:`x_{i+1} - x_0`), ``d`` 2 or 3.
        P: Edge vectors of the direction, same shape.

    Returns:
        ``(a0, a1, a2, a3)``, arrays of shape ``(n,)``.

    Raises:
        ParameterError: If the shapes are not ``(n, d, d)`` with ``d`` 2 or 3 and equal.
    """
    return _coefficients(*_component_major(D, P, "volume_ratio_coefficients"))


def _critical_points(b: np.ndarray, c: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""Real roots of :math:`g'(\alpha) = b + 2c\alpha + 3d\alpha^2` (``nan`` where there is none).

    Cancellation-free form: :math:`q = -(c + \operatorname{sign}(c)\sqrt{c^2 - 3bd})`,
    roots :math:`q / 3d` and :math:`b / q`; :math:`d = 0` gives the linear root
    :math:`-b/2c` (and an infinite one), :math:`q = 0` (then :math:`b = 0`
    or :math:`d = 0` with :math:`c = 0`) gives none that matters.
    """
    disc = c * c - 3.0 * b * d
    with np.errstate(invalid="ignore", divide="ignore"):
        root = np.sqrt(np.where(disc >= 0.0, disc, np.nan))
        q = -(c + np.where(c >= 0.0, 1.0, -1.0) * root)
        r1 = q / (3.0 * d)
        r2 = b / q
    return r1, r2


def _cubic(t: np.ndarray, g0: float | np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Horner evaluation of :math:`g_0 + bt + ct^2 + dt^3`."""
    return g0 + t * (b + t * (c + t * d))


def first_volume_crossing(
    b: np.ndarray, c: np.ndarray, d: np.ndarray, volume_fraction: float = DEFAULT_VOLUME_FRACTION
) -> np.ndarray:
    r"""Smallest :math:`\alpha \in (0, 1]` with :math:`1 + b\alpha + c\alpha^2 + d\alpha^3 = \eta`, or 1 if none.

    Vectorized over cells (see the module docstring for the method). The
    result is the left end of a bracket of width below :math:`2^{-60}`, where
    the polynomial was evaluated above :math:`\eta`: it is never past the root.

    Args:
        b: Linear coefficients of the volume ratio, shape ``(n,)``.
        c: Quadratic coefficients.
        d: Cubic coefficients (zeros in 2D).
        volume_fraction: :math:`\eta \in (0, 1)`.

    Returns:
        :math:`\alpha` per cell; 1 where the ratio stays above :math:`\eta` on
        :math:`[0, 1]`; non-finite coefficients give 1 (nothing to filter).

    Raises:
        ParameterError: If ``volume_fraction`` is not in (0, 1).
    """
    eta = float(volume_fraction)
    if not 0.0 < eta < 1.0:
        raise ParameterError(f"first_volume_crossing: volume_fraction must be in (0, 1), got {volume_fraction!r}")
    b, c, d = (np.asarray(v, dtype=float) for v in (b, c, d))
    g0 = 1.0 - eta
    alpha = np.ones(b.shape)
    finite = np.isfinite(b) & np.isfinite(c) & np.isfinite(d)
    # Breakpoints 0 < t1 <= t2 <= t3 = 1 between which g is monotone.
    r1, r2 = _critical_points(b, c, d)
    inside = lambda r: np.where(np.isfinite(r) & (r > 0.0) & (r < 1.0), r, 1.0)  # noqa: E731
    t1 = np.minimum(inside(r1), inside(r2))
    t2 = np.maximum(inside(r1), inside(r2))
    t3 = np.ones(b.shape)
    breaks = np.stack([np.zeros(b.shape), t1, t2, t3])
    with np.errstate(invalid="ignore", over="ignore"):
        values = np.stack([np.full(b.shape, g0), *(_cubic(t, g0, b, c, d) for t in (t1, t2, t3))])
    crossed = (values[1:] <= 0.0) & finite
    hit = np.any(crossed, axis=0)
    if not np.any(hit):
        return alpha
    first = np.argmax(crossed[:, hit], axis=0)  # index 0..2 of the first breakpoint with g <= 0
    idx = np.nonzero(hit)[0]
    lo = breaks[first, idx]
    hi = breaks[first + 1, idx]
    bh, ch, dh = b[idx], c[idx], d[idx]
    # g(lo) > 0 >= g(hi), g monotone on [lo, hi]: bisection keeps that invariant.
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        above = _cubic(mid, g0, bh, ch, dh) > 0.0
        lo = np.where(above, mid, lo)
        hi = np.where(above, hi, mid)
    alpha[idx] = lo
    return alpha


def max_step_fractions(D: np.ndarray, P: np.ndarray, volume_fraction: float = DEFAULT_VOLUME_FRACTION) -> np.ndarray:
    r"""Per cell, the largest :math:`\alpha \in (0, 1]` with :math:`\det(D + tP) > \eta \det D` for :math:`t < \alpha`.

    Args:
        D: Current edge vectors, shape ``(n, d, d)``.
        P: Edge vectors of the direction, same shape.
        volume_fraction: :math:`\eta \in (0, 1)`.

    Returns:
        :math:`\alpha` per cell (1 where no limit is needed; also 1 for cells
        that are already degenerate, :math:`\det D = 0`, which the caller's
        :math:`J` check must refuse).
    """
    return _fractions(*_component_major(D, P, "max_step_fractions"), volume_fraction)


def _fractions(D: np.ndarray, P: np.ndarray, volume_fraction: float) -> np.ndarray:
    """:func:`max_step_fractions` of component-major arrays."""
    a0, a1, a2, a3 = _coefficients(D, P)
    with np.errstate(invalid="ignore", divide="ignore"):
        b, c, d = a1 / a0, a2 / a0, a3 / a0
    return first_volume_crossing(b, c, d, volume_fraction)


def exact_filter_applies(V: fem.FunctionSpace) -> bool:
    """Whether ``V`` is a P1 vector space on straight simplices (the exact filter applies).

    Needs a blocked Lagrange element of degree 1 with ``gdim`` components on a
    triangle or tetrahedron mesh with an affine coordinate map and
    ``gdim == tdim``.
    """
    mesh = V.mesh
    tdim, gdim = mesh.topology.dim, mesh.geometry.dim
    if mesh.topology.cell_type not in _SIMPLICES or tdim != gdim:
        return False
    if mesh.geometry.cmaps[0].degree != 1:
        return False
    if V.dofmap.bs != gdim or V.num_sub_spaces != gdim:
        return False
    try:
        element = V.element.basix_element
    except (AttributeError, RuntimeError, ValueError):
        return False
    import basix

    return element.family == basix.ElementFamily.P and element.degree == 1 and element.dim == tdim + 1


class StepFilter:
    r"""The exact inversion-free step length on a P1 vector space (see the module docstring).

    Built once per space: the cell → dof table and the reference node
    coordinates of the owned cells are cached, :meth:`max_step` is then a few
    vectorized array operations and one ``allreduce``.

    Args:
        V: The displacement space (see :func:`exact_filter_applies`).
        volume_fraction: :math:`\eta \in (0, 1)`, default :data:`DEFAULT_VOLUME_FRACTION`.

    Raises:
        ParameterError: If ``V`` is not a P1 vector space on straight simplices,
            or ``volume_fraction`` is not in (0, 1).
    """

    def __init__(self, V: fem.FunctionSpace, volume_fraction: float = DEFAULT_VOLUME_FRACTION):
        if not exact_filter_applies(V):
            raise ParameterError(
                "StepFilter: the exact step filter needs a P1 vector displacement on straight triangles/tetrahedra "
                f"(got {V.ufl_element()} on {V.mesh.topology.cell_type.name})"
            )
        eta = float(volume_fraction)
        if not 0.0 < eta < 1.0:
            raise ParameterError(f"StepFilter: volume_fraction must be in (0, 1), got {volume_fraction!r}")
        self.volume_fraction = eta
        self.comm = V.mesh.comm
        mesh = V.mesh
        tdim = mesh.topology.dim
        self.gdim = mesh.geometry.dim
        owned = mesh.topology.index_map(tdim).size_local
        cells = np.asarray(V.dofmap.list[:owned], dtype=np.int64)  # (n, tdim + 1) block dofs
        g = self.gdim
        # Flat indices into a function's local array, component-major: [node, component, cell].
        self._index = (cells.T[:, None, :] * g + np.arange(g)[None, :, None]).reshape(-1)
        self._shape = (tdim + 1, g, cells.shape[0])
        X = V.tabulate_dof_coordinates()[:, :g].reshape(-1)  # P1 on an affine mesh: the vertices
        self._X_edges = self._edges(X)

    def _edges(self, values: np.ndarray) -> np.ndarray:
        """Component-major edge vectors ``(d, d, n)`` of the owned cells of a function's local array."""
        v = np.take(np.asarray(values, dtype=float), self._index).reshape(self._shape)
        return v[1:] - v[0]

    def cell_fractions(self, u: np.ndarray, p: np.ndarray) -> np.ndarray:
        r"""Per owned cell, the largest admissible :math:`\alpha` (local, no reduction).

        Args:
            u: Current displacement, the local array (owned and ghost values)
                of a function on the space.
            p: The direction (trial state ``u + alpha * p``), same layout; its
                ghost values must be up to date.
        """
        return _fractions(self._X_edges + self._edges(u), self._edges(p), self.volume_fraction)

    def volume_ratios(self, u: np.ndarray, p: np.ndarray, alpha: float) -> np.ndarray:
        r"""Per owned cell, :math:`\det D(\alpha) / \det D(0)` from the determinants themselves (for checks)."""
        return self._ratios(self._X_edges + self._edges(u), self._edges(p), alpha)

    @staticmethod
    def _ratios(D: np.ndarray, P: np.ndarray, alpha: float) -> np.ndarray:
        with np.errstate(invalid="ignore", divide="ignore"):
            return _det(D + alpha * P) / _det(D)

    def max_step(self, u: np.ndarray, p: np.ndarray) -> float:
        r"""The largest :math:`\alpha \in (0, 1]` such that no cell shrinks below :math:`\eta` of its volume.

        Collective (``allreduce`` MIN of the step, LAND of the check). The
        step is checked against the directly evaluated determinants; should
        round-off in the coefficients of a badly shaped cell let a ratio fall
        below :math:`\eta/2` there, the step is halved until it does not.

        Args:
            u: Current displacement (local array with up-to-date ghosts).
            p: The direction, trial state ``u + alpha * p`` (same layout,
                up-to-date ghosts).

        Returns:
            :math:`\alpha`, the same on every rank (1 when nothing limits the step).
        """
        D = self._X_edges + self._edges(u)
        P = self._edges(p)
        local = _fractions(D, P, self.volume_fraction)
        alpha = float(local.min()) if local.size else 1.0
        alpha = self.comm.allreduce(alpha, op=MPI.MIN)
        for _ in range(BISECTION_STEPS):
            ratios = self._ratios(D, P, alpha)
            finite = np.isfinite(ratios)
            ok = bool(np.all(ratios[finite] >= 0.5 * self.volume_fraction))
            if self.comm.allreduce(ok, op=MPI.LAND):
                break
            alpha *= 0.5
        return alpha
