r"""Energies of the principal stretches, smooth where the stretches coincide.

An isotropic energy is a symmetric function of the eigenvalues
:math:`c_i = \lambda_i^2` of :math:`C = F^TF`. This module evaluates

.. math::
    \Sigma_f(C) = \sum_{i=1}^3 f(c_i)

for a smooth scalar :math:`f` (:func:`eigenvalue_sum`) as a UFL expression whose
first *and second* derivatives, taken by ``ufl.derivative``, are exact to
round-off everywhere: at :math:`C = I`, on every uniaxial or equibiaxial state
(a double eigenvalue) and between. On it are built Hencky's (Riemannian)
energy, the volume-preserving energy and Saint Venant–Kirchhoff written in
stretches (seed 003, §4.5.1, eqs. 4.73a–c); Ogden's (4.73d) is in
:mod:`hyperfem.materials.ogden`.

**Why closed-form eigenvalues fail.** With :math:`m = \operatorname{tr}C/3`,
:math:`D = C - mI`, :math:`J_2 = \frac12 D:D`, :math:`J_3 = \det D`, the
eigenvalues are :math:`c_k = m + \rho\,y_k` with :math:`\rho = 2\sqrt{J_2/3}` and
:math:`y_k` the roots of the Chebyshev cubic :math:`4y^3 - 3y = x`,
:math:`x = 4J_3/\rho^3 \in [-1, 1]` (Cardano: :math:`y = \cos(\arccos(x)/3 - 2\pi k/3)`).
:math:`\rho` has an infinite derivative at :math:`J_2 = 0` (:math:`C = sI`), and
:math:`\arccos` at :math:`|x| = 1` (a double eigenvalue), where also
:math:`\partial x/\partial C = 0`: the chain rule gives :math:`0\cdot\infty` = NaN.
The *sum* :math:`\Sigma_f` is nevertheless smooth (a symmetric analytic function
of the eigenvalues is an analytic function of :math:`C`); only the route through
the individual eigenvalues is singular. Known remedies and their errors on the
tangent: ε-clamps in Cardano are right at :math:`C = I` and 37 % off at every
double eigenvalue; dolfiny's ``eigenstate3`` 1.35× off at :math:`I` and 13.8× at a
double eigenvalue; a fixed shift :math:`C + 10^{-8}\operatorname{diag}(1, 0, -1)`
is within 6e-8 everywhere with a stress bias of 5e-9.

**What is done here** (no shift, no clamp that is active where it is used).
Four exact representations of :math:`\Sigma_f`, each smooth where it is
selected, are switched by ``ufl.conditional`` (a conditional's derivative is the
derivative of the selected branch, so each derivative is exact wherever the
selected branch is):

1. *Near* :math:`C = sI` (:math:`\rho \le r_T m`, :data:`ISOTROPIC_SPREAD`): the
   Taylor series about :math:`m`,
   :math:`\Sigma_f = 3f(m) + \sum_{n=2}^{N} \frac{f^{(n)}(m)}{n!}\operatorname{tr}D^n`,
   with :math:`\operatorname{tr}D^n` polynomials in :math:`J_2, J_3`
   (:math:`p_{n+3} = J_2 p_{n+1} + J_3 p_n`), :math:`N` = :data:`ISOTROPIC_ORDER`.
   The truncation is :math:`\sim\binom{\beta}{N+1} r_T^{N+1}` relative for
   :math:`f = c^\beta`.
2. *Otherwise* the eigenvalue farthest from the other two,
   :math:`c_* = m + \operatorname{sign}(x)\,\rho\,y_*` (the largest if :math:`x \ge 0`,
   else the smallest), is simple, and the two others are
   :math:`\bar c \pm \sqrt q` with :math:`\bar c = m - \operatorname{sign}(x)\rho y_*/2`,
   :math:`q = \frac34\rho^2(1 - y_*^2)`. The root :math:`y_*(|x|)` of the cubic is
   analytic up to and beyond :math:`|x| = 1`. It is Cardano's
   :math:`\cos(\arccos|x|/3)` for :math:`|x| \le` :data:`DOUBLE_ROOT_BRANCH`; above,
   :math:`\delta = 1 - y_*` solves :math:`t - 9\delta + 12\delta^2 - 4\delta^3 = 0`,
   :math:`t = 1 - |x|`, from its series :math:`t/9 + 4t^2/243 + 28t^3/6561` plus
   one Newton step (no :math:`\arccos`, so round-off that puts :math:`|x|`
   above 1 is harmless).
3. The pair sum :math:`g = f(\bar c + \sqrt q) + f(\bar c - \sqrt q)` is even in
   :math:`\sqrt q`: for :math:`\sqrt q \le r_P\bar c` (:data:`PAIR_SPREAD`) it is
   :math:`2\sum_{k=0}^{K} f^{(2k)}(\bar c)\,q^k/(2k)!` (:math:`K` =
   :data:`PAIR_ORDER`), a polynomial in :math:`q`, so smooth through
   :math:`q = 0`; above, the closed form.

Every singular operation is fed a guarded argument (``max_value``/``min_value``
that is inactive in the branch that uses it), so no branch, selected or not,
ever computes an infinity or a NaN. The series coefficients come from ``ufl.diff``
for a general :math:`f` (:func:`eigenvalue_sum`), and are written out for sums of
powers (:func:`eigenvalue_power_sum`, Ogden) and for :math:`(\ln c)^2` (Hencky),
which makes the generated code smaller. Ogden terms with even exponents need no
eigenvalues at all: :math:`\sum_i c_i^k` are polynomials in the invariants
(:func:`invariant_power_sum`), and so is the volume-preserving energy.

**Thresholds and measured errors.** A series truncated at order :math:`N` makes
a tangent error :math:`\sim r^{N-1}` at its switch :math:`r`; the exact formulas
beyond it lose :math:`\sim\epsilon/r^2` to cancellation. :math:`N = 5` with
:math:`r_T = 10^{-3}` and :math:`K = 2` with :math:`r_P = 5\cdot 10^{-4}` balance
the two; eight and four terms reach 1e-14 but make a tangent with 50 % more C
code. Against exact references (``benchmarks/materials_principal.py``: the Ogden
sum with exponents (2, 4, -2), whose stretch sums are
:math:`\operatorname{tr}\bar C, \operatorname{tr}\bar C^2, \operatorname{tr}\bar C^{-1}`;
and mpmath's 60-digit eigenvalues with finite differences for Ogden (1.3, 5, -2)
and Hencky), the largest errors of the tangent :math:`\partial^2\psi/\partial F^2`,
relative to its largest entry, are

* 4e-16 at :math:`F = I`, 5e-16 at three distinct stretches, 5e-16 at exact
  uniaxial stretch 1.5 and equibiaxial 2 (rotated copies included), 4e-14 at
  uniaxial stretch 5 (Hencky: 1e-12, whose :math:`C` spans a factor 125);
* 2e-12 in the worst of 140 random states 1e-6..1e-2 from :math:`C = sI` (the
  truncation at :math:`r_T`), 2e-13 in 120 states with a pair 1e-6..1e-2 apart;

and of the stress, 4e-16 :math:`\mu_0` (1e-12 :math:`\mu_0` at uniaxial stretch 5,
where :math:`P \approx 200\mu_0`). There is no bias: nothing is perturbed.

**Cost.** Forward-mode differentiation makes every node of the branches carry
the 81 monomials of the tangent, so the generated C is large. On the 6×6×6 unit
cube (1296 P1 tetrahedra; ``benchmarks/materials_principal.py``, CPU seconds of
``dolfinx.fem.form`` including the C compiler, DOLFINx's default ``-O2``):

=========================  ==========  ==============  ==================
tangent form               C code      compile (CPU)   one assembly (CPU)
=========================  ==========  ==============  ==================
neo-Hookean                0.10 MB     1.0 s           5.5 ms
Ogden-3 (1.3, 5, -2)       1.7 MB      18 s            11 ms
Ogden-3 (1.3, 5, -2.5)     1.9 MB      23 s            11 ms
Hencky                     1.4 MB      16 s            13 ms
SVK in stretches           0.97 MB     6.8 s           10 ms
=========================  ==========  ==============  ==================

(SVK in stretches: another run, neo-Hookean 0.62 s and 3.6 ms in it; the residual
forms: 0.15 MB, about 1 s). With ``jit_options =
{"cffi_extra_compile_args": ["-O0", "-g0"]}`` Ogden's tangent compiles in 4 s and
assembles in 80 ms: the choice for tests and small meshes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import ufl

from hyperfem.kinematics import jacobian, plane_strain_3d, right_cauchy_green
from hyperfem.materials.parameters import LameParameters
from hyperfem.validation import check_positive

__all__ = [
    "DOUBLE_ROOT_BRANCH",
    "ISOTROPIC_ORDER",
    "ISOTROPIC_SPREAD",
    "PAIR_ORDER",
    "PAIR_SPREAD",
    "SpectralInvariants",
    "eigenvalue_power_sum",
    "eigenvalue_sum",
    "hencky",
    "invariant_power_sum",
    "saint_venant_kirchhoff_principal",
    "spectral_invariants",
    "volume_preservation",
]

Expr = ufl.core.expr.Expr
ScalarFunction = Callable[[Expr], Expr]

ISOTROPIC_SPREAD = 1e-3
r""":math:`r_T`: the Taylor series about :math:`m` is used while :math:`\rho = 2\sqrt{J_2/3} \le r_T m`."""

ISOTROPIC_ORDER = 5
r""":math:`N`: the highest power of :math:`D` in the series about :math:`m`."""

DOUBLE_ROOT_BRANCH = 0.99
r"""Above this :math:`|x|` the isolated root comes from its series and a Newton step, not from :math:`\arccos`."""

PAIR_SPREAD = 5e-4
r""":math:`r_P`: the pair sum is a series in :math:`q` while the half gap :math:`\sqrt q \le r_P \bar c`."""

PAIR_ORDER = 2
r""":math:`K`: the highest power of :math:`q` in the pair series."""


@dataclass(frozen=True)
class SpectralInvariants:
    r""":math:`(m, J_2, J_3)` of a symmetric 3×3 tensor (:func:`spectral_invariants`).

    Attributes:
        mean: :math:`m = \operatorname{tr}C/3`.
        J2: :math:`\frac12 D:D`, :math:`D = C - mI`.
        J3: :math:`\det D`.
    """

    mean: Expr
    J2: Expr
    J3: Expr

    def scaled(self, s: Expr | float) -> SpectralInvariants:
        r"""The invariants of :math:`sC`, :math:`(sm, s^2J_2, s^3J_3)` (:math:`s = J^{-2/3}`: of :math:`\bar C`)."""
        return SpectralInvariants(s * self.mean, s**2 * self.J2, s**3 * self.J3)


def spectral_invariants(C: Expr) -> SpectralInvariants:
    r"""The mean and deviatoric invariants :math:`(m, J_2, J_3)` of a symmetric 3×3 tensor.

    :math:`m = \operatorname{tr}C/3`, :math:`D = C - mI`, :math:`J_2 = \frac12 D:D`,
    :math:`J_3 = \det D` (from :math:`D`, not from :math:`I_1, I_2, I_3`, which would cancel
    near :math:`C = sI`).
    """
    if C.ufl_shape != (3, 3):
        raise ValueError(f"spectral_invariants: need a 3x3 tensor, got shape {C.ufl_shape}")
    m = ufl.tr(C) / 3.0
    D = C - m * ufl.Identity(3)
    return SpectralInvariants(m, 0.5 * ufl.inner(D, D), ufl.det(D))


class _Series(Protocol):
    r""":math:`f` and the two series of :math:`\Sigma_f` that the degenerate branches use."""

    def value(self, c: Expr) -> Expr: ...

    def about_mean(self, m: Expr, J2: Expr, J3: Expr) -> Expr: ...

    def pair(self, c: Expr, q: Expr) -> Expr: ...


def _power_traces(J2: Expr, J3: Expr, n: int) -> list[Expr | float]:
    r""":math:`p_k = \operatorname{tr}D^k`, :math:`k = 0..n`, of a traceless 3×3 :math:`D` (Newton's identities)."""
    p: list[Expr | float] = [3.0, 0.0, 2.0 * J2]
    while len(p) <= n:
        k = len(p)
        p.append(J2 * p[k - 2] + J3 * p[k - 3])
    return p[: n + 1]


@dataclass(frozen=True)
class _GenericSeries:
    """Any smooth :math:`f`; its derivatives by ``ufl.diff``."""

    f: ScalarFunction

    def _derivatives(self, at: Expr, n: int) -> list[Expr]:
        v = ufl.variable(at)
        out = [self.f(v)]
        for _ in range(n):
            out.append(ufl.diff(out[-1], v))
        return out

    def value(self, c: Expr) -> Expr:
        return self.f(c)

    def about_mean(self, m: Expr, J2: Expr, J3: Expr) -> Expr:
        fm = self._derivatives(m, ISOTROPIC_ORDER)
        p = _power_traces(J2, J3, ISOTROPIC_ORDER)
        return 3.0 * fm[0] + sum(fm[n] * p[n] / math.factorial(n) for n in range(2, ISOTROPIC_ORDER + 1))

    def pair(self, c: Expr, q: Expr) -> Expr:
        fc = self._derivatives(c, 2 * PAIR_ORDER)
        return 2.0 * sum(fc[2 * k] * q**k / math.factorial(2 * k) for k in range(PAIR_ORDER + 1))


def _binomial(beta: float, n: int) -> float:
    out = 1.0
    for i in range(n):
        out *= (beta - i) / (i + 1)
    return out


@dataclass(frozen=True)
class _PowerSeries:
    r""":math:`f(c) = \sum_p k_p(c^{\beta_p} - 1)`: series with binomial coefficients (smaller than by ``ufl.diff``)."""

    terms: tuple[tuple[Expr | float, float], ...]

    def value(self, c: Expr) -> Expr:
        return sum(k * (c**beta - 1.0) for k, beta in self.terms)

    def about_mean(self, m: Expr, J2: Expr, J3: Expr) -> Expr:
        # f^(n)(m)/n! tr D^n = k binom(beta, n) m^beta p_n(J2/m^2, J3/m^3)
        p = _power_traces(J2 / m**2, J3 / m**3, ISOTROPIC_ORDER)
        return sum(
            k * (m**beta * (3.0 + sum(_binomial(beta, n) * p[n] for n in range(2, ISOTROPIC_ORDER + 1))) - 3.0)
            for k, beta in self.terms
        )

    def pair(self, c: Expr, q: Expr) -> Expr:
        z = q / c**2
        return sum(
            k * (2.0 * c**beta * sum(_binomial(beta, 2 * j) * z**j for j in range(PAIR_ORDER + 1)) - 2.0)
            for k, beta in self.terms
        )


@dataclass(frozen=True)
class _LogSquareSeries:
    r""":math:`f(c) = (\ln c)^2`: :math:`f^{(n)}(c) = (-1)^{n-1}(n-1)!\,2(\ln c - H_{n-1})/c^n`, :math:`H` harmonic."""

    @staticmethod
    def _coefficient(n: int) -> tuple[float, float]:
        r""":math:`f^{(n)}(c)\,c^n/n! = a + b\ln c`; returns ``(a, b)``."""
        harmonic = sum(1.0 / i for i in range(1, n))
        sign = (-1.0) ** (n - 1)
        return -2.0 * sign * harmonic / n, 2.0 * sign / n

    def value(self, c: Expr) -> Expr:
        return ufl.ln(c) ** 2

    def about_mean(self, m: Expr, J2: Expr, J3: Expr) -> Expr:
        L = ufl.ln(m)
        p = _power_traces(J2 / m**2, J3 / m**3, ISOTROPIC_ORDER)
        terms = [self._coefficient(n) for n in range(2, ISOTROPIC_ORDER + 1)]
        return (
            3.0 * L**2
            + sum(a * p[n] for n, (a, _) in enumerate(terms, 2))
            + L * sum(b * p[n] for n, (_, b) in enumerate(terms, 2))
        )

    def pair(self, c: Expr, q: Expr) -> Expr:
        L = ufl.ln(c)
        z = q / c**2
        terms = [(self._coefficient(2 * k), z**k) for k in range(1, PAIR_ORDER + 1)]
        return 2.0 * (L**2 + sum(a * zk for (a, _), zk in terms) + L * sum(b * zk for (_, b), zk in terms))


def _isolated_root(u: Expr) -> tuple[Expr, Expr]:
    r"""The largest root :math:`y_*` of :math:`4y^3 - 3y = u \in [0, 1]` and :math:`q_y = \frac34(1 - y_*^2)`.

    Both smooth through :math:`u = 1` (module docstring, step 2).
    """
    # Cardano below the branch point (the guard is inactive where this branch is selected).
    theta = ufl.acos(ufl.min_value(u, DOUBLE_ROOT_BRANCH)) / 3.0
    y_cardano = ufl.cos(theta)
    q_cardano = 0.75 * ufl.sin(theta) ** 2
    # Near the double root: delta = 1 - y from its series in t = 1 - u and one Newton step.
    t = 1.0 - ufl.max_value(u, DOUBLE_ROOT_BRANCH)
    d = t / 9.0 + 4.0 * t**2 / 243.0 + 28.0 * t**3 / 6561.0
    d = d - (t - 9.0 * d + 12.0 * d**2 - 4.0 * d**3) / (-9.0 + 24.0 * d - 12.0 * d**2)
    near = ufl.gt(u, DOUBLE_ROOT_BRANCH)
    y = ufl.conditional(near, 1.0 - d, y_cardano)
    q_y = ufl.conditional(near, 0.75 * d * (2.0 - d), q_cardano)
    return y, q_y


def _spectral_sum(inv: SpectralInvariants, series: _Series) -> Expr:
    """The four branches of the module docstring."""
    m, J2, J3 = inv.mean, inv.J2, inv.J3
    isotropic_limit = 0.75 * ISOTROPIC_SPREAD**2 * m**2  # J2 at rho = r_T m

    # 2. The isolated eigenvalue and the pair.
    rho = 2.0 * ufl.sqrt(ufl.max_value(J2, isotropic_limit) / 3.0)
    x = 4.0 * J3 / rho**3
    sign = ufl.conditional(ufl.ge(x, 0.0), 1.0, -1.0)
    y, q_y = _isolated_root(sign * x)
    c_isolated = m + sign * rho * y
    c_pair = m - 0.5 * sign * rho * y
    q = rho**2 * q_y

    # 3. The pair sum, even in sqrt(q).
    pair_limit = PAIR_SPREAD**2 * c_pair**2
    half_gap = ufl.sqrt(ufl.max_value(q, pair_limit))
    pair_closed = series.value(c_pair + half_gap) + series.value(c_pair - half_gap)
    pair = ufl.conditional(ufl.le(q, pair_limit), series.pair(c_pair, q), pair_closed)

    # 1. Near C = sI: the series about m.
    return ufl.conditional(ufl.le(J2, isotropic_limit), series.about_mean(m, J2, J3), series.value(c_isolated) + pair)


def eigenvalue_sum(C: Expr | SpectralInvariants, f: ScalarFunction) -> Expr:
    r""":math:`\sum_i f(c_i)` over the eigenvalues of a symmetric positive-definite 3×3 tensor (module docstring).

    Args:
        C: The tensor (e.g. :math:`C = F^TF`), or its :class:`SpectralInvariants`.
        f: Scalar function, smooth on :math:`(0, \infty)`, written with UFL
            operators (``ufl.diff`` takes its derivatives, up to order
            :data:`ISOTROPIC_ORDER` + 2).

    Returns:
        A scalar UFL expression whose first and second derivatives are exact
        (to round-off) at equal and distinct eigenvalues alike.
    """
    inv = C if isinstance(C, SpectralInvariants) else spectral_invariants(C)
    return _spectral_sum(inv, _GenericSeries(f))


def eigenvalue_power_sum(
    C: Expr | SpectralInvariants, coefficients: Sequence[Expr | float], exponents: Sequence[float]
) -> Expr:
    r""":math:`\sum_p k_p \sum_i (c_i^{\beta_p} - 1)`: :func:`eigenvalue_sum` of a sum of powers, with a smaller form.

    The same branches, with the series coefficients written as binomials
    :math:`\binom{\beta_p}{n}` instead of derived by ``ufl.diff`` (about 17 % less
    generated code for Ogden's tangent).

    Args:
        C: The tensor, or its :class:`SpectralInvariants`.
        coefficients: :math:`k_p`.
        exponents: :math:`\beta_p` (any real numbers).
    """
    inv = C if isinstance(C, SpectralInvariants) else spectral_invariants(C)
    return _spectral_sum(inv, _PowerSeries(tuple(zip(coefficients, (float(b) for b in exponents), strict=True))))


def invariant_power_sum(I1: Expr, I2: Expr, I3: Expr | float, k: int) -> Expr:
    r""":math:`\sum_i c_i^k = \operatorname{tr}C^k` for an integer :math:`k \ne 0`, from the principal invariants.

    Newton's identities, :math:`p_k = I_1 p_{k-1} - I_2 p_{k-2} + I_3 p_{k-3}` with
    :math:`p_0 = 3`; a negative :math:`k` uses the invariants of :math:`C^{-1}`,
    :math:`(I_2/I_3, I_1/I_3, 1/I_3)`. A polynomial (or rational) function of
    :math:`C`, smooth everywhere: this is how Ogden terms with an even exponent
    are evaluated (:mod:`hyperfem.materials.ogden`).

    Args:
        I1, I2, I3: Principal invariants of :math:`C`.
        k: Nonzero integer power.
    """
    if not isinstance(k, int) or isinstance(k, bool) or k == 0:
        raise ValueError(f"invariant_power_sum: need a nonzero integer power, got {k!r}")
    if k < 0:
        I1, I2, I3, k = I2 / I3, I1 / I3, 1.0 / I3, -k
    p: list[Any] = [3.0, I1, I1 * I1 - 2.0 * I2]  # (numbers work too)
    while len(p) <= k:
        n = len(p)
        p.append(I1 * p[n - 1] - I2 * p[n - 2] + I3 * p[n - 3])
    return p[k]


def _C3(F: Expr) -> Expr:
    return right_cauchy_green(plane_strain_3d(F))


def hencky(F: Expr, params: LameParameters) -> Expr:
    r"""Hencky's (Riemannian) energy, seed 003 eq. 4.73b.

    .. math::
        \psi = \mu\sum_i(\ln\lambda_i)^2 + \frac{\lambda}{2}\Big(\sum_i\ln\lambda_i\Big)^2
             = \frac{\mu}{4}\sum_i(\ln c_i)^2 + \frac{\lambda}{2}(\ln J)^2

    (:math:`\mu|\ln U|^2 + \frac\lambda2\operatorname{tr}^2\ln U`; the seed writes it in the
    eigenvalues :math:`c_i` of :math:`C`). Linear elasticity with :math:`\mu, \lambda` at small strain.

    Args:
        F: Deformation gradient (3×3, or 2×2 in plane strain).
        params: Lamé parameters.
    """
    log_sum = _spectral_sum(spectral_invariants(_C3(F)), _LogSquareSeries())
    return 0.25 * params.mu * log_sum + 0.5 * params.lmbda * ufl.ln(jacobian(plane_strain_3d(F))) ** 2


def volume_preservation(F: Expr, k: float | Expr = 1.0) -> Expr:
    r"""Volume-preservation energy, seed 003 eq. 4.73a: :math:`k\,(\prod_i\lambda_i - 1)^2 = k\,(J - 1)^2`.

    The product of the principal stretches is :math:`\sqrt{\det C} = J` (for :math:`J > 0`), an
    invariant: no eigenvalues are needed, and the energy is a polynomial in :math:`F`. It has no
    shear stiffness: a penalty term to add to a material, not a material.

    Args:
        F: Deformation gradient (3×3, or 2×2 in plane strain).
        k: Penalty coefficient (> 0).
    """
    if isinstance(k, (int, float)):
        check_positive("k", k, "volume_preservation")
    return k * (jacobian(plane_strain_3d(F)) - 1.0) ** 2


def saint_venant_kirchhoff_principal(F: Expr, params: LameParameters) -> Expr:
    r"""Saint Venant–Kirchhoff in the eigenvalues :math:`c_i` of :math:`C` (seed 003 eq. 4.73c, corrected).

    .. math::
        \psi = \frac{\mu}{4}\sum_i(c_i - 1)^2 + \frac{\lambda}{8}\Big(\sum_i(c_i - 1)\Big)^2
             = \mu\,E:E + \frac\lambda2(\operatorname{tr}E)^2,

    the Green strain having eigenvalues :math:`(c_i - 1)/2`. The seed prints
    :math:`c_i^{1/2} - 1` (the Biot strain), which is not Saint Venant–Kirchhoff
    (a quarter of its stiffness at small strain); this is, and equals
    :func:`~hyperfem.materials.saint_venant_kirchhoff.saint_venant_kirchhoff` to round-off (tested).

    Args:
        F: Deformation gradient (3×3, or 2×2 in plane strain).
        params: Lamé parameters.
    """
    inv = spectral_invariants(_C3(F))
    return (
        0.25 * params.mu * eigenvalue_sum(inv, lambda c: (c - 1.0) ** 2)
        + 0.125 * params.lmbda * eigenvalue_sum(inv, lambda c: c - 1.0) ** 2
    )
