r"""Prony series: the relaxation function of finite-strain viscoelasticity and its one-step factors.

The normalised shear relaxation function is

.. math::
    g(t) = g_\infty + \sum_{i=1}^{N} g_i\,e^{-t/\tau_i},\qquad g_\infty = 1 - \sum_i g_i,

with relative moduli :math:`g_i \ge 0`, :math:`\sum_i g_i < 1` (so the
long-term modulus :math:`g_\infty` is positive) and relaxation times
:math:`\tau_i > 0`. Over a step :math:`\Delta t` the convolution
:math:`\int e^{-(t-s)/\tau_i}\dot S(s)\,ds` of a stress :math:`S` that is
linear in time within the step is exact with the factors

.. math::
    c_i = e^{-\Delta t/\tau_i},\qquad
    a_i = \frac{\tau_i}{\Delta t}\bigl(1 - e^{-\Delta t/\tau_i}\bigr)\quad(a_i \to 1 \text{ as } \Delta t \to 0)

(:meth:`PronySeries.step_factors`), which is what
:mod:`hyperfem.materials.viscoelastic` integrates with. The same factors
give the closed form of a linear ramp of strain to :math:`\varepsilon_0` over
:math:`[0, t_r]` held from then on, in linear viscoelasticity with modulus
:math:`E_0 g(t)`:

.. math::
    \sigma(t) = E_0\varepsilon_0\Bigl[g_\infty + \sum_i g_i\,a_i(t_r)\,e^{-(t - t_r)/\tau_i}\Bigr]\quad(t \ge t_r)

(:meth:`PronySeries.ramp_and_hold`).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hyperfem.errors import ParameterError
from hyperfem.validation import is_finite_number

__all__ = ["PronySeries", "ramp_and_hold_factors"]


def _as_tuple(values: object, name: str, where: str) -> tuple[float, ...]:
    """``values`` as a tuple of finite floats (a single number is refused: say ``(0.3,)``)."""
    if isinstance(values, (str, bytes)) or isinstance(values, numbers.Number) or not hasattr(values, "__iter__"):
        raise ParameterError(f"{where}: {name} must be a sequence of numbers, e.g. (0.3,), got {values!r}")
    items = list(values)  # any iterable the user gives
    bad = [v for v in items if not is_finite_number(v)]
    if bad:
        raise ParameterError(f"{where}: {name} must hold finite numbers, got {bad[0]!r}")
    return tuple(float(v) for v in items)


@dataclass(frozen=True)
class PronySeries:
    r"""Relative moduli and relaxation times of :math:`g(t) = g_\infty + \sum_i g_i e^{-t/\tau_i}`.

    Attributes:
        g: Relative moduli :math:`g_i \ge 0` with :math:`\sum_i g_i < 1` (dimensionless).
        tau: Relaxation times :math:`\tau_i > 0`, one per modulus (time units, e.g. s).

    Raises:
        ParameterError: On an empty series, lengths that differ, a negative or
            non-finite :math:`g_i`, :math:`\sum_i g_i \ge 1`, or :math:`\tau_i \le 0`.
    """

    g: Sequence[float]
    tau: Sequence[float]

    def __post_init__(self) -> None:
        where = "PronySeries"
        g = _as_tuple(self.g, "g", where)
        tau = _as_tuple(self.tau, "tau", where)
        if not g:
            raise ParameterError(f"{where}: g is empty (give at least one term, e.g. g=(0.3,), tau=(1.0,))")
        if len(g) != len(tau):
            raise ParameterError(f"{where}: {len(g)} moduli g but {len(tau)} relaxation times tau")
        for i, (gi, ti) in enumerate(zip(g, tau, strict=True)):
            if gi < 0.0:
                raise ParameterError(f"{where}: g[{i}] must be >= 0, got {gi!r}")
            if not ti > 0.0:
                raise ParameterError(f"{where}: tau[{i}] must be > 0, got {ti!r}")
        if not sum(g) < 1.0:
            raise ParameterError(
                f"{where}: the moduli must sum to less than 1 (g_inf = 1 - sum(g) > 0), got sum(g) = {sum(g):g}"
            )
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "tau", tau)

    @property
    def terms(self) -> int:
        """Number of terms :math:`N`."""
        return len(self.g)

    @property
    def g_inf(self) -> float:
        r"""Long-term relative modulus :math:`g_\infty = 1 - \sum_i g_i > 0`."""
        return 1.0 - math.fsum(self.g)

    def relaxation(self, t: float | np.ndarray) -> float | np.ndarray:
        r"""The relaxation function :math:`g(t) = g_\infty + \sum_i g_i e^{-t/\tau_i}` (1 at :math:`t = 0`)."""
        times = np.asarray(t, dtype=float)
        out = np.full(times.shape, self.g_inf)
        for gi, ti in zip(self.g, self.tau, strict=True):
            out = out + gi * np.exp(-times / ti)
        return float(out) if out.ndim == 0 else out

    def step_factors(self, dt: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        r"""The factors :math:`(c_i, a_i)` of a step :math:`\Delta t \ge 0` (module docstring).

        :math:`a_i = -\operatorname{expm1}(-x_i)/x_i` with :math:`x_i = \Delta t/\tau_i`
        (no cancellation for small steps); :math:`\Delta t = 0` gives
        :math:`c_i = a_i = 1` (the instantaneous response).

        Raises:
            ParameterError: ``dt`` is negative or not finite.
        """
        if not (is_finite_number(dt) and dt >= 0.0):
            raise ParameterError(f"PronySeries: a step must be a finite time >= 0, got {dt!r}")
        c, a = [], []
        for ti in self.tau:
            x = float(dt) / ti
            c.append(math.exp(-x))
            a.append(-math.expm1(-x) / x if x > 0.0 else 1.0)
        return tuple(c), tuple(a)

    def ramp_and_hold(self, t: float | np.ndarray, t_ramp: float) -> float | np.ndarray:
        r"""Linear-viscoelastic stress of a linear ramp over :math:`[0, t_r]` then held, over the instantaneous one.

        .. math::
            \frac{\sigma(t)}{E_0\varepsilon(t)} =
            \begin{cases}
              g_\infty + \sum_i g_i\,a_i(t)\ &t \le t_r \\
              g_\infty + \sum_i g_i\,a_i(t_r)\,e^{-(t - t_r)/\tau_i}\ &t \ge t_r
            \end{cases}

        with :math:`a_i(s) = (\tau_i/s)(1 - e^{-s/\tau_i})` and :math:`\varepsilon(t)`
        the strain at :math:`t` (:math:`\varepsilon_0` once held). Multiply by
        :math:`E_0\varepsilon_0` (the stress an elastic solid would carry at the held
        strain) for :math:`P(t)` after the ramp.

        Args:
            t: Times :math:`\ge 0`.
            t_ramp: Ramp duration :math:`t_r > 0`.
        """
        if not (is_finite_number(t_ramp) and t_ramp > 0.0):
            raise ParameterError(f"PronySeries.ramp_and_hold: t_ramp must be a finite number > 0, got {t_ramp!r}")
        times = np.asarray(t, dtype=float)
        out = self.g_inf + ramp_and_hold_factors(times.reshape(-1), t_ramp, self.tau) @ np.asarray(self.g)
        return float(out[0]) if times.ndim == 0 else out.reshape(times.shape)


def ramp_and_hold_factors(
    t: np.ndarray | Sequence[float], t_ramp: float, tau: np.ndarray | Sequence[float]
) -> np.ndarray:
    r"""Each term's factor :math:`a_i(\min(t, t_r))\,e^{-\max(t - t_r, 0)/\tau_i}` of :meth:`PronySeries.ramp_and_hold`.

    The stress of a ramp over :math:`[0, t_r]` then held is
    :math:`E_0\varepsilon(t)\,[g_\infty + \sum_i g_i A_{ni}]` with :math:`A` this matrix:
    linear in :math:`g_\infty` and the :math:`g_i` for given :math:`\tau_i`, which is how
    :func:`~hyperfem.materials.prony_fit.fit_prony` fits them. :math:`t_r = 0` is a step
    of strain (:math:`a_i = 1`: :math:`A_{ni} = e^{-t_n/\tau_i}`).

    Args:
        t: Times :math:`\ge 0`, shape ``(n,)``.
        t_ramp: Ramp duration :math:`t_r \ge 0`.
        tau: Relaxation times :math:`\tau_i > 0`, shape ``(N,)``.

    Returns:
        The factors, shape ``(n, N)``.
    """
    times = np.asarray(t, dtype=float).reshape(-1, 1)
    taus = np.asarray(tau, dtype=float).reshape(1, -1)
    x = np.minimum(times, t_ramp) / taus
    positive = x > 0.0
    a = np.where(positive, -np.expm1(-x) / np.where(positive, x, 1.0), 1.0)
    return a * np.exp(-np.maximum(times - t_ramp, 0.0) / taus)
