r"""A Prony series fitted to relaxation data: the :class:`~hyperfem.materials.prony.PronySeries` of a ``Viscoelastic``.

.. code-block:: python

    import hyperfem as hf

    data = hf.materials.read_relaxation("RELAX.csv", ramp_time=0.5)  # stress at a held strain, or g(t)
    result = hf.materials.fit("prony", data, terms=2)                 # or fit_prony(data, terms=2)
    print(result.summary())                                          # g, tau, rms, the [material.viscoelastic] table
    psi = hf.materials.Viscoelastic(elastic, result.prony)           # the series as the solver takes it

**Data** (:func:`read_relaxation`): a CSV file with a header and the columns
``time_s`` (time in s from the start of the loading, :math:`\ge 0`) and either
``nominal_stress_MPa`` (the nominal stress of a test held at one strain, in MPa:
*stress* data) or ``relaxation_modulus`` (the normalised relaxation function
:math:`g(t) = G(t)/G(0)`, 1 at :math:`t = 0`: *modulus* data); other columns are
ignored. The strain is ramped linearly over :math:`[0, t_r]` (``ramp_time``,
default 0: a step of strain) and held from then on. A file of hyperelastic test
data (:func:`~hyperfem.materials.fitting.read_curves`, a column ``mode``) with a
column ``time_s`` gives its rows of mode ``relaxation`` (one test: every such row
at the same ``stretch``, the uniaxial stretch held); its other modes are left out.

**Model.** The response is the closed form of the issue (Simo 1987, linear
viscoelasticity) that :meth:`PronySeries.ramp_and_hold` evaluates, with its
terms from :func:`~hyperfem.materials.prony.ramp_and_hold_factors` (no second
formula):

.. math::
    P(t) = P_0\,r(t)\Bigl[g_\infty + \sum_i g_i\,a_i(\min(t, t_r))\,e^{-\max(t - t_r, 0)/\tau_i}\Bigr],\qquad
    r(t) = \min(t/t_r, 1),

with :math:`P_0` the instantaneous stress of the held strain (stress data: fitted;
modulus data: 1). It is also the solver's: the step recursion of
:mod:`~hyperfem.materials.viscoelastic` is exact for an isochoric stress linear in
time, so a small-strain ramp and hold of a :class:`Viscoelastic` bar follows it
to :math:`O(\varepsilon_0)` at any time step that lands on :math:`t_r`
(``tests/test_viscoelastic.py``). At larger strain the rubber's nonlinearity
enters; fit :math:`g(t)` from a small-strain test, or read the fitted
:math:`g_i` as those of the isochoric stress.

**Least squares.** For given :math:`\tau_i` the model is linear in
:math:`h_0 = P_0 g_\infty` and :math:`h_i = P_0 g_i`: non-negative least squares
(Lawson–Hanson) gives them with :math:`h \ge 0`. Relaxation times not given are
fitted too (``terms`` of them): variable projection, Levenberg–Marquardt on
:math:`\ln\tau_i` with the :math:`h` of each trial from the non-negative least
squares, started from times spaced evenly in :math:`\ln t` over the data (and
from those three times shorter and longer; the best is kept). Given times
(``tau``) are kept unless ``fit_tau=True`` refines them. Residuals are relative
(``weighting="relative"``, each point :math:`1/|P_i|`) or absolute.

**Result** (:class:`PronyFit`): the :class:`PronySeries` (sorted by
:math:`\tau`), :math:`P_0`, the rms, relative rms and largest relative error
(``errors["relaxation"]``), and each term's share of the rms if it were left out
(:attr:`PronyFit.term_rms`: how much each term carries), a ``[material.viscoelastic]``
table for a case file.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hyperfem.errors import OutputError, ParameterError
from hyperfem.materials.fitting import (
    RELAXATION_MODE,
    WEIGHTINGS,
    ModeError,
    _did_you_mean,
    _least_squares,
    _read_rows,
)
from hyperfem.materials.prony import PronySeries, ramp_and_hold_factors
from hyperfem.validation import is_finite_number

__all__ = [
    "RELAXATION_COLUMNS",
    "RELAXATION_KINDS",
    "PronyFit",
    "RelaxationCurve",
    "fit_prony",
    "plot_relaxation",
    "read_relaxation",
]

RELAXATION_KINDS = {"stress": "nominal_stress_MPa", "modulus": "relaxation_modulus"}
"""The kinds of relaxation data and their CSV columns (module docstring)."""

RELAXATION_COLUMNS = ("time_s", *RELAXATION_KINDS.values())
"""The columns of :func:`read_relaxation`: the time and one of the two values."""

DEFAULT_TERMS = 3
"""Terms of a fit without given relaxation times."""


@dataclass(frozen=True, eq=False)
class RelaxationCurve:
    r"""A relaxation test: the stress at a held strain, or :math:`g(t)`, against time, sorted by time.

    Attributes:
        time: Times :math:`\ge 0` from the start of the loading (s).
        value: Nominal stress (``kind="stress"``, the data's unit) or normalised
            relaxation modulus (``kind="modulus"``, dimensionless, 1 at :math:`t = 0`).
        kind: ``"stress"`` or ``"modulus"``.
        ramp_time: Duration :math:`t_r \ge 0` of the linear ramp of strain (0: a step).
    """

    time: np.ndarray
    value: np.ndarray
    kind: str = "stress"
    ramp_time: float = 0.0

    def __post_init__(self) -> None:
        where = "fit: relaxation data"
        if self.kind not in RELAXATION_KINDS:
            raise ParameterError(f"{where}: kind must be one of {', '.join(RELAXATION_KINDS)}, got {self.kind!r}")
        if not (is_finite_number(self.ramp_time) and self.ramp_time >= 0.0):
            raise ParameterError(f"{where}: ramp_time must be a finite number >= 0 (s), got {self.ramp_time!r}")
        t = np.asarray(self.time, dtype=float).reshape(-1)
        y = np.asarray(self.value, dtype=float).reshape(-1)
        if t.size == 0 or t.shape != y.shape:
            raise ParameterError(f"{where}: need as many values as times (>= 1), got {t.size} and {y.size}")
        if not (np.isfinite(t).all() and np.isfinite(y).all()):
            raise ParameterError(f"{where}: times and values must be finite numbers")
        if (t < 0.0).any():
            raise ParameterError(f"{where}: times must be >= 0 (from the start of the loading), got {t.min():g}")
        order = np.argsort(t, kind="stable")
        t, y = t[order], y[order]
        held = t >= self.ramp_time
        if self.kind == "modulus" and not (y > 0.0).all():
            raise ParameterError(f"{where}: a relaxation modulus g(t) must be > 0, got {y.min():g}")
        if self.kind == "stress" and not ((y[held] > 0.0).all() or (y[held] < 0.0).all()):
            raise ParameterError(f"{where}: the stress at the held strain must keep one sign, non-zero (one test at "
                                 "one strain)")
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "value", y)
        object.__setattr__(self, "ramp_time", float(self.ramp_time))

    def strain_fraction(self, t: np.ndarray | None = None) -> np.ndarray:
        r""":math:`r(t) = \min(t/t_r, 1)` (1 for a step) at ``t`` (default the data's times)."""
        times = self.time if t is None else np.asarray(t, dtype=float)
        if self.ramp_time == 0.0:
            return np.ones_like(times)
        return np.minimum(times / self.ramp_time, 1.0)


def read_relaxation(path: str | Path, ramp_time: float = 0.0) -> RelaxationCurve:
    """The :class:`RelaxationCurve` of a CSV file (module docstring).

    Args:
        path: The CSV file: ``time_s`` and ``nominal_stress_MPa`` or ``relaxation_modulus``
            (with a column ``mode``: its rows of mode ``relaxation``).
        ramp_time: Duration of the ramp of strain (s; 0: a step).

    Raises:
        ParameterError: Missing file or column, both value columns, a value that is not a finite
            number (naming file and line), a negative time; with a ``mode`` column: no relaxation
            rows, or relaxation rows at more than one stretch.
    """
    path = Path(path)
    need = "time_s and nominal_stress_MPa or relaxation_modulus"
    rows = _read_rows(path, need)
    header = [h.strip() for h in rows[0]]
    modes = header.index("mode") if "mode" in header else None
    if "time_s" not in header:
        hint = _did_you_mean("time_s", header)
        if not hint and modes is not None and any(
            len(row) > modes and row[modes].strip() == RELAXATION_MODE for row in rows[1:]
        ):
            hint = f" (its rows of mode {RELAXATION_MODE} need the time of each point)"
        elif not hint and "stretch" in header:
            hint = " (these are hyperelastic test data: fit them with a hyperelastic law)"
        raise ParameterError(f"fit: {path}: no column 'time_s'{hint}; relaxation data need the columns {need} "
                             f"(found: {', '.join(header) or 'none'})")
    kinds = [k for k, column in RELAXATION_KINDS.items() if column in header]
    if len(kinds) != 1:
        what = "both" if kinds else "neither"
        near = "" if kinds else next((_did_you_mean(c, header) for c in RELAXATION_KINDS.values()
                                      if _did_you_mean(c, header)), "")
        raise ParameterError(f"fit: {path}: {what} of the columns nominal_stress_MPa and relaxation_modulus{near}; "
                             "give one (stress at a held strain, or g(t))")
    kind = kinds[0]
    columns = {"time_s": header.index("time_s"), kind: header.index(RELAXATION_KINDS[kind])}
    if modes is not None and "stretch" in header:
        columns["stretch"] = header.index("stretch")
    times, values, stretches, others = [], [], set(), set()
    for line, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        where = f"fit: {path}:{line}"
        if modes is not None and (len(row) <= modes or row[modes].strip() != RELAXATION_MODE):
            others.add(row[modes].strip() if len(row) > modes else "")
            continue
        if len(row) <= max(columns.values()):
            raise ParameterError(f"{where}: {len(row)} columns, the header has {len(header)}")
        numbers = []
        for name, index in columns.items():
            text = row[index].strip()
            column = RELAXATION_KINDS.get(name, name)
            try:
                value = float(text)
            except ValueError:
                raise ParameterError(f"{where}: {column} must be a number, got {text!r}") from None
            if not math.isfinite(value):
                raise ParameterError(f"{where}: {column} must be a finite number, got {text!r}")
            numbers.append(value)
        if numbers[0] < 0.0:
            raise ParameterError(f"{where}: time_s must be >= 0 (from the start of the loading), got {numbers[0]!r}")
        if len(numbers) > 2:
            if not numbers[2] > 0.0:
                raise ParameterError(f"{where}: stretch must be > 0, got {numbers[2]!r}")
            stretches.add(numbers[2])
        times.append(numbers[0])
        values.append(numbers[1])
    if not times and modes is not None:
        found = ", ".join(sorted(others)) or "none"
        raise ParameterError(f"fit: {path}: no rows of mode {RELAXATION_MODE} (modes found: {found}): fit these data "
                             "with a hyperelastic law")
    if not times:
        raise ParameterError(f"fit: {path} has no data rows")
    if len(stretches) > 1:
        held = ", ".join(f"{v:g}" for v in sorted(stretches))
        raise ParameterError(f"fit: {path}: relaxation rows at {len(stretches)} stretches ({held}): one relaxation "
                             "test (one held stretch) per fit")
    return RelaxationCurve(np.array(times), np.array(values), kind, ramp_time)


# -- least squares ---------------------------------------------------------------------------------------
def _nnls(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Lawson–Hanson non-negative least squares, :math:`\\min\\|Ax - b\\|` subject to :math:`x \\ge 0`."""
    norms = np.linalg.norm(A, axis=0)
    norms = np.where(norms > 0.0, norms, 1.0)
    M = A / norms  # unit columns: the tolerances compare like with like
    n = M.shape[1]
    x = np.zeros(n)
    passive = np.zeros(n, dtype=bool)
    tol = 10.0 * np.finfo(float).eps * max(M.shape) * max(1.0, float(np.linalg.norm(b)))
    for _ in range(3 * n + 3):
        w = M.T @ (b - M @ x)
        if passive.all() or not (w[~passive] > tol).any():
            break
        passive[np.argmax(np.where(passive, -np.inf, w))] = True
        while True:
            z = np.zeros(n)
            z[passive] = np.linalg.lstsq(M[:, passive], b, rcond=None)[0]
            if (z[passive] > 0.0).all():
                break
            negative = passive & (z <= 0.0)
            alpha = float(np.min(x[negative] / (x[negative] - z[negative])))
            x = x + alpha * (z - x)
            passive &= x > tol
            x[~passive] = 0.0
            if not passive.any():
                z = np.zeros(n)
                break
        x = z
    return x / norms


def _system(curve: RelaxationCurve, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(M, y)``: the data are ``M h`` with ``h >= 0`` (stress: ``h = P0 (g_inf, g_i)``; modulus: ``h = g``)."""
    r = curve.strain_fraction()[:, None]
    A = ramp_and_hold_factors(curve.time, curve.ramp_time, tau)
    if curve.kind == "stress":
        sign = 1.0 if curve.value[curve.time >= curve.ramp_time][0] > 0 else -1.0
        return np.hstack([r, r * A]), sign * curve.value
    return r * (A - 1.0), curve.value - r[:, 0]


def _weights(curve: RelaxationCurve, weighting: str) -> np.ndarray:
    y = np.abs(curve.value)
    if weighting == "absolute":
        return np.ones_like(y)
    floor = float(np.sqrt(np.mean(y**2))) or 1.0
    return 1.0 / np.where(y > 0.0, y, floor)


@dataclass(frozen=True)
class _Trial:
    tau: np.ndarray
    h: np.ndarray
    cost: float
    iterations: int
    converged: bool


def _solve(curve: RelaxationCurve, tau: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    M, y = _system(curve, tau)
    h = _nnls(weights[:, None] * M, weights * y)
    return h, weights * (M @ h - y)


def _fit_times(curve: RelaxationCurve, start: np.ndarray, weights: np.ndarray, max_iterations: int) -> _Trial:
    """Variable projection: Levenberg–Marquardt on ln(tau), h from the non-negative least squares of each trial."""
    positive = curve.time[curve.time > 0.0]
    low = math.log(float(positive.min()) / 100.0)
    high = math.log(float(curve.time.max()) * 100.0)
    lower, upper = np.full(start.size, low), np.full(start.size, high)

    def residual(z: np.ndarray) -> np.ndarray:
        return _solve(curve, np.exp(z), weights)[1]

    z0 = np.clip(np.log(start), low, high)
    solution = _least_squares(residual, z0, lower, upper, np.full(start.size, 1e-3), max_iterations)
    tau = np.exp(solution.x)
    h, r = _solve(curve, tau, weights)
    return _Trial(tau, h, 0.5 * float(r @ r), solution.iterations, solution.converged)


# -- the result --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class PronyFit:
    """The fitted Prony series, its errors, and the curve to plot.

    Attributes:
        prony: The series (sorted by relaxation time): pass it to
            :class:`~hyperfem.materials.viscoelastic.Viscoelastic`.
        instantaneous: :math:`P_0`, the instantaneous stress of the held strain (data unit;
            1 for modulus data).
        data: The fitted :class:`RelaxationCurve`.
        model: The fitted response at the data's times.
        errors: ``{"relaxation": ModeError}`` (the data's unit).
        term_rms: For each term, the rms of the fit with that term left out (the others kept):
            how much of the fit it carries.
        tau_fitted: Whether the relaxation times were fitted (else given).
        weighting: ``"relative"`` or ``"absolute"``.
        iterations: Levenberg–Marquardt iterations on the times (0: given times).
        converged: Whether the optimiser stopped at a minimum.
    """

    prony: PronySeries
    instantaneous: float
    data: RelaxationCurve
    model: np.ndarray
    errors: dict[str, ModeError]
    term_rms: tuple[float, ...]
    tau_fitted: bool
    weighting: str
    iterations: int
    converged: bool

    law = "prony"

    @property
    def terms(self) -> int:
        """Number of terms."""
        return self.prony.terms

    @property
    def label(self) -> str:
        """``prony (N terms)``."""
        return f"prony ({self.terms} term{'s' if self.terms != 1 else ''})"

    @property
    def unit(self) -> str:
        """The unit of the data: ``MPa`` (stress data) or ``1`` (modulus data)."""
        return "MPa" if self.data.kind == "stress" else "1"

    def response(self, t: Sequence[float] | np.ndarray) -> np.ndarray:
        r"""The fitted :math:`P(t)` (or :math:`g(t)` of modulus data) of the data's ramp (module docstring)."""
        times = np.asarray(t, dtype=float).reshape(-1)
        if self.data.ramp_time > 0.0:
            g = np.asarray(self.prony.ramp_and_hold(times, self.data.ramp_time))
        else:
            g = np.asarray(self.prony.relaxation(times))
        return self.instantaneous * self.data.strain_fraction(times) * g

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready summary: ``law``, ``parameters`` ``{g, tau}``, ``g_inf``, errors, term rms."""
        rms_key = "rms_MPa" if self.data.kind == "stress" else "rms"
        out: dict[str, Any] = {
            "law": self.law,
            "terms": self.terms,
            "data": self.data.kind,
            "parameters": {"g": list(self.prony.g), "tau": list(self.prony.tau)},
            "g_inf": self.prony.g_inf,
            "ramp_time_s": self.data.ramp_time,
            rms_key: {m: e.rms for m, e in self.errors.items()},
            "relative_rms": {m: e.relative_rms for m, e in self.errors.items()},
            "max_relative": {m: e.max_relative for m, e in self.errors.items()},
            "term_rms": list(self.term_rms),
            "tau_fitted": self.tau_fitted,
            "weighting": self.weighting,
            "converged": self.converged,
            "iterations": self.iterations,
        }
        if self.data.kind == "stress":
            out["instantaneous_stress_MPa"] = self.instantaneous
        return out

    def summary(self) -> str:
        """The series, the errors and each term's share as text."""
        how = "relaxation times fitted" if self.tau_fitted else "relaxation times given"
        state = "" if not self.tau_fitted else (
            f", {'converged' if self.converged else 'NOT converged'} in {self.iterations} iterations")
        lines = [f"{self.label}, {self.data.kind} data, {self.weighting} least squares ({how}{state})"]
        if self.data.kind == "stress":
            lines.append(f"  instantaneous stress P0 = {self.instantaneous:.6g} {self.unit}")
        lines.append(f"  {'term':<6} {'g_i':>12} {'tau_i [s]':>12} {'rms without [' + self.unit + ']':>22}")
        for i, (g, tau) in enumerate(zip(self.prony.g, self.prony.tau, strict=True)):
            lines.append(f"  {i + 1:<6} {g:>12.6g} {tau:>12.6g} {self.term_rms[i]:>22.4g}")
        lines.append(f"  g_inf = {self.prony.g_inf:.6g}")
        e = self.errors["relaxation"]
        lines.append(f"  {'mode':<12} {'points':>6} {'rms [' + self.unit + ']':>12} {'rel. rms':>9} {'max rel.':>9}")
        lines.append(f"  {'relaxation':<12} {e.points:>6} {e.rms:>12.4g} {e.relative_rms:>9.2%} {e.max_relative:>9.2%}")
        return "\n".join(lines)

    def case_table(self) -> str:
        """A ``[material.viscoelastic]`` table (times in s) to paste under a ``[[material]]`` of a split law."""
        g = ", ".join(f"{v:.6g}" for v in self.prony.g)
        tau = ", ".join(f"{v:.6g}" for v in self.prony.tau)
        return (f"# {self.label} fitted to relaxation {self.data.kind} data; times in s\n"
                f"[material.viscoelastic]\ng = [{g}]\ntau = [{tau}]\n")


# -- the fit ---------------------------------------------------------------------------------------------
def _times(values: object, name: str) -> np.ndarray:
    if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
        raise ParameterError(f"fit: {name} must be a sequence of relaxation times in s, e.g. (0.1, 1.0), "
                             f"got {values!r}")
    items = list(values)  # any iterable
    if not items or not all(is_finite_number(v) and v > 0 for v in items):
        raise ParameterError(f"fit: {name} must hold relaxation times > 0 (s), got {items!r}")
    return np.array(items, dtype=float)


def fit_prony(
    data: RelaxationCurve | str | Path,
    *,
    terms: int | None = None,
    tau: Sequence[float] | None = None,
    fit_tau: bool | None = None,
    ramp_time: float | None = None,
    weighting: str = "relative",
    max_iterations: int = 200,
) -> PronyFit:
    """Least-squares fit of a Prony series to relaxation data (module docstring).

    Args:
        data: A :class:`RelaxationCurve`, or a CSV path (:func:`read_relaxation`).
        terms: Number of terms with fitted relaxation times (default 3; with ``tau``: its length).
        tau: Relaxation times (s): kept fixed unless ``fit_tau``.
        fit_tau: Fit the times (default: only when ``tau`` is not given).
        ramp_time: Ramp duration of a CSV path (s, default 0); a curve carries its own.
        weighting: ``"relative"`` (default) or ``"absolute"`` residuals.
        max_iterations: Levenberg–Marquardt iterations on the times per start.

    Returns:
        The :class:`PronyFit`.

    Raises:
        ParameterError: Bad data or options, fewer points than unknowns plus one, or data that
            relax completely (:math:`\\sum_i g_i \\ge 1`: no long-term modulus).
    """
    if isinstance(data, (str, Path)):
        curve = read_relaxation(data, 0.0 if ramp_time is None else ramp_time)
    elif isinstance(data, RelaxationCurve):
        curve = data
        if ramp_time is not None and ramp_time != curve.ramp_time:
            raise ParameterError(f"fit: ramp_time {ramp_time!r} differs from the data's {curve.ramp_time!r} "
                                 "(a RelaxationCurve carries its ramp)")
    else:
        raise ParameterError(f"fit: prony needs relaxation data (a RelaxationCurve or a CSV with time_s), "
                             f"got {type(data).__name__}")
    if weighting not in WEIGHTINGS:
        raise ParameterError(f"fit: weighting must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
    if terms is not None and (not isinstance(terms, int) or isinstance(terms, bool) or not 1 <= terms <= 12):
        raise ParameterError(f"fit: terms must be an integer from 1 to 12, got {terms!r}")
    given = None if tau is None else _times(tau, "tau")
    if given is not None and terms is not None and terms != given.size:
        raise ParameterError(f"fit: terms = {terms} but {given.size} relaxation times tau given")
    fit_times = given is None if fit_tau is None else bool(fit_tau)
    n = given.size if given is not None else (terms or DEFAULT_TERMS)
    unknowns = n * (2 if fit_times else 1) + (1 if curve.kind == "stress" else 0)
    if curve.time.size <= unknowns:
        raise ParameterError(
            f"fit: {curve.time.size} relaxation points for {unknowns} unknowns ({n} g_i"
            f"{f', {n} tau_i' if fit_times else ''}{', P0' if curve.kind == 'stress' else ''}): need at least "
            f"{unknowns + 1} (or fewer terms)")
    if fit_times and np.unique(curve.time[curve.time > 0.0]).size < 2:
        raise ParameterError("fit: fitting relaxation times needs at least two distinct times > 0")
    weights = _weights(curve, weighting)

    if not fit_times:
        assert given is not None
        h, r = _solve(curve, given, weights)
        best = _Trial(given, h, 0.5 * float(r @ r), 0, True)
    else:
        if given is not None:
            starts = [given]
        else:
            positive = curve.time[curve.time > 0.0]
            grid = np.exp(np.linspace(math.log(positive.min()), math.log(positive.max()), n + 2)[1:-1])
            starts = [grid, grid / 3.0, grid * 3.0]
        trials = [_fit_times(curve, s, weights, max_iterations) for s in starts]
        best = min(trials, key=lambda trial: trial.cost)

    order = np.argsort(best.tau, kind="stable")
    tau_fit = best.tau[order]
    if curve.kind == "stress":
        sign = 1.0 if curve.value[curve.time >= curve.ramp_time][0] > 0 else -1.0
        total = float(best.h.sum())
        if not total > 0.0 or not best.h[0] > 1e-12 * total:
            raise ParameterError(
                "fit: the fitted series relaxes completely (g_inf = 0, sum of g_i = 1): a Prony series needs a "
                "long-term modulus; give data of a longer hold or fewer terms")
        P0, g = sign * total, best.h[1:][order] / total
    else:
        P0, g = 1.0, best.h[order]
        if not float(g.sum()) < 1.0:
            raise ParameterError(
                f"fit: the fitted moduli sum to {g.sum():.6g} >= 1 (g_inf <= 0): a Prony series needs a long-term "
                "modulus (is relaxation_modulus normalised to 1 at t = 0?)")
    try:
        prony = PronySeries(g=tuple(float(v) for v in g), tau=tuple(float(v) for v in tau_fit))
    except ParameterError as exc:
        raise ParameterError(f"fit: the fitted series is refused: {exc}") from None

    def model_of(series_g: np.ndarray) -> np.ndarray:
        A = ramp_and_hold_factors(curve.time, curve.ramp_time, tau_fit)
        return P0 * curve.strain_fraction() * (1.0 - series_g.sum() + A @ series_g)

    model = model_of(g)
    error = _mode_error(curve, model)
    term_rms = []
    for i in range(n):
        without = g.copy()
        without[i] = 0.0
        term_rms.append(float(np.sqrt(np.mean((model_of(without) - curve.value) ** 2))))
    return PronyFit(prony=prony, instantaneous=float(P0), data=curve, model=model,
                    errors={"relaxation": error}, term_rms=tuple(term_rms), tau_fitted=fit_times,
                    weighting=weighting, iterations=best.iterations, converged=best.converged)


def _mode_error(curve: RelaxationCurve, model: np.ndarray) -> ModeError:
    diff = model - curve.value
    nonzero = curve.value != 0.0
    relative = np.abs(diff[nonzero] / curve.value[nonzero]) if nonzero.any() else np.zeros(1)
    return ModeError(points=int(curve.time.size), rms=float(np.sqrt(np.mean(diff**2))),
                     relative_rms=float(np.sqrt(np.mean(relative**2))), max_relative=float(np.max(relative)))


def plot_relaxation(result: PronyFit, path: str | Path, *, title: str | None = None) -> Path:
    """A PNG of the relaxation data (markers) and the fitted series (line) against time (matplotlib, Agg).

    Raises:
        OutputError: matplotlib missing, or the file cannot be written.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise OutputError("plot_relaxation: needs matplotlib (pip install 'hyperfem[plot]')") from None
    data = result.data
    fig, ax = plt.subplots(figsize=(6.0, 4.2))
    ax.plot(data.time, data.value, "ko", markersize=4, label="data")
    t = np.union1d(np.linspace(0.0, float(data.time.max()), 400), [data.ramp_time])  # the kink at t_r drawn
    e = result.errors["relaxation"]
    ax.plot(t, result.response(t), "-", linewidth=1.4, label=f"{result.label}: rms {e.rms:.3g} {result.unit}")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("nominal stress P₁₁ [MPa]" if data.kind == "stress" else "relaxation modulus g(t) [-]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title or result.label, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    try:
        fig.savefig(path, dpi=120)
    except OSError as exc:
        raise OutputError(f"plot_relaxation: cannot write {path}: {exc}") from None
    finally:
        plt.close(fig)
    return path
