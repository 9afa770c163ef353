r"""Material parameters fitted to homogeneous test data by least squares.

.. code-block:: python

    import hyperfem as hf

    data = hf.materials.read_curves("DATA.csv")        # or hf.materials.treloar_data()
    result = hf.materials.fit("ogden", data, terms=3)  # incompressible: no volumetric data, no bulk_modulus
    print(result.summary())                            # parameters, rms per mode, Drucker stability
    print(result.case_table(stress_factor=1e6))        # a [[material]] table in Pa, ready to paste
    hf.materials.plot_fits([result], "fit.png")

**Data** (:func:`read_curves`): a CSV file with a header and the columns
``mode`` (``uniaxial``, ``equibiaxial``, ``pure_shear`` or ``volumetric``, the
modes of :mod:`~hyperfem.materials.homogeneous`), ``stretch`` (the stretch
:math:`\lambda` along the loading, dimensionless; for ``volumetric`` the stretch
:math:`J^{1/3}` of :math:`F = \lambda I`) and ``nominal_stress_MPa`` (the nominal —
first Piola–Kirchhoff — stress :math:`P_{11}`, force per undeformed area, in MPa;
volumetric: :math:`P_{11} = -p\,J^{2/3}` for a pressure :math:`p`); other
columns are ignored. The fitted moduli are in the data's unit (MPa).
An optional column ``fibre_angle_deg`` (:data:`ANGLE_COLUMN`) gives the fibre angle
:math:`\theta` of each test of a fibre-reinforced specimen, in degrees in :math:`[-90, 90]`: the
angle between the fibres and the loading direction :math:`e_1`, in the :math:`e_1`–:math:`e_2`
plane, with ``holzapfel_gasser_ogden``'s two families at :math:`\pm\theta` (the usual
symmetric arrangement: the test axes are axes of symmetry, a test does not shear).
Each (mode, angle) is then its own curve, keyed ``mode@angle`` (``uniaxial@30``),
with its own rms; an equibiaxial test's :math:`P_{22}` is the row of the angle
:math:`90 - \theta`.
The same file may hold relaxation tests: rows of mode ``relaxation`` with a
column ``time_s`` (s from the start of the loading), ``stretch`` the uniaxial
stretch held and ``nominal_stress_MPa`` the stress at that time. The
hyperelastic laws leave them out (:func:`relaxation_rows` counts them);
``law="prony"`` fits them (:func:`~hyperfem.materials.prony_fit.read_relaxation`).
Treloar's 1944 data ship with hyperfem (:func:`treloar_data`, the file
``hyperfem/materials/data/treloar1944.csv`` and its source note beside it).
Relaxation data (time and the stress at a held strain, or :math:`g(t)`) are fitted
with ``law="prony"``: a :class:`~hyperfem.materials.prony.PronySeries` for a
:class:`~hyperfem.materials.viscoelastic.Viscoelastic`
(:mod:`~hyperfem.materials.prony_fit`, :func:`~hyperfem.materials.prony_fit.read_relaxation`).

**Model.** The response of each law is that of its own UFL energy
(:class:`~hyperfem.materials.homogeneous.HomogeneousResponse`: the law's
``*_isochoric`` part with the pressure eliminated by the traction-free face for an
*incompressible* fit, the default; the full energy with its volumetric term
:math:`U(J)` and the lateral stretch solved for a *compressible* one, which needs
``bulk_modulus`` or ``volumetric`` data). The parameters are
:class:`dolfinx.fem.Constant`\ s: each law compiles once, whatever the optimiser
tries. The laws and what is fitted (:data:`FIT_LAWS`; each parameter within the
range its parameter class accepts):

* ``neo_hookean``: :math:`\mu > 0`;
* ``mooney_rivlin``: :math:`c_1 > 0`, :math:`c_2 \ge 0`;
* ``yeoh``: :math:`C_{10} > 0`, :math:`C_{20}`, :math:`C_{30}` (any sign; the stability check tells);
* ``reduced_polynomial``: :math:`C_{10} > 0, C_{20}, \dots, C_{N0}` (``terms`` = N, default 3);
* ``gent``: :math:`\mu > 0`, :math:`J_m` above the largest :math:`\bar I_1 - 3` of the data;
* ``arruda_boyce``: :math:`\mu > 0`, :math:`\lambda_m > 1`;
* ``veronda_westmann``: :math:`c_1 > 0`, :math:`c_2 > 0`;
* ``ogden`` (``terms`` = N, default 3): :math:`\mu_p, \alpha_p` with :math:`\mu_p\alpha_p > 0` for every
  term (:class:`~hyperfem.materials.ogden.OgdenParameters` asks it), the sign of each
  :math:`\alpha_p` kept from its start (default starts: Ogden's 1972 exponents
  :math:`1.3, 5, -2` and two others; the best fit is kept). The energy is
  :func:`~hyperfem.materials.principal_stretches.eigenvalue_sum` of
  :math:`\bar C` with :math:`f(c) = \sum_p\frac{\mu_p}{\alpha_p}(c^{\alpha_p/2} - 1)`, the form
  :func:`~hyperfem.materials.ogden.ogden_isochoric` evaluates, written with the
  exponents as constants (that function takes them as numbers, which would
  recompile at every new :math:`\alpha`).

* ``holzapfel_gasser_ogden`` (curves with a fibre angle, incompressible only): :math:`\mu > 0`,
  :math:`k_1 \ge 0`, :math:`k_2 > 0`, :math:`\kappa \in [0, 1/3]`, the tension-only switch ``strain``
  (its default); the uniaxial lateral stretches, which differ, from the free faces
  (:meth:`~hyperfem.materials.homogeneous.HomogeneousResponse.states`). Two angles (or
  uniaxial with equibiaxial) separate the matrix from the fibres. The table adds
  ``[fibres]`` and ``[second_fibres]`` (constant, :math:`(\cos\theta, \pm\sin\theta, 0)` of the
  first angle: the directions of the geometry replace them). ``muscle``'s active part is no passive
  property;
* ``weiss`` (curves with a fibre angle 0 or 90 only, incompressible): :math:`c_1 > 0`, :math:`c_2, c_3, c_5 \ge 0`,
  :math:`c_4 \in [10^{-3}, 500]`, :math:`\lambda^* \in (1, 2]`; its one family along :math:`(\cos\theta, \sin\theta, 0)`
  (at another angle a test of one family shears); the toe integral with 64 Gauss points
  (:data:`_WEISS_POINTS`; the law's own count depends on :math:`c_4, \lambda^*`). The table adds ``[fibres]``;
* ``fung_orthotropic`` (curves with a fibre angle 0 or 90 only, incompressible): its axes :math:`a_1 =
  (\cos\theta, \sin\theta, 0)`, :math:`a_2 = (-\sin\theta, \cos\theta, 0)` (at another angle a test of
  orthotropic axes shears); :math:`c > 0`, :math:`b_1, b_2, b_3 \in [10^{-6}, 10^3]`, :math:`b_4, b_5, b_6 \in
  [-10^3, 10^3]` (the normal block positive definite: the parameter class checks it). The shear constants
  :math:`b_7, b_8, b_9` must be given in ``fixed``: along the material axes :math:`E_{12} = E_{23} = E_{31} = 0`, no
  test of these modes strains them. The table adds ``[fibres]`` (:math:`a_1`) and ``[second_fibres]`` (:math:`a_2`).
  The couplings are weakly determined: :math:`\tilde E` is isochoric, so at small strain the tests see the normal
  block only on :math:`\operatorname{tr}\tilde E \approx 0`. Uniaxial 1.02-1.3 and equibiaxial 1.02-1.2 at 0 and
  90 degrees with 1 % noise (4 seeds): :math:`c, b_1, b_2` within 5 %, :math:`b_3` 15 %, :math:`b_4, b_5, b_6`
  up to 38 %; exact data give all seven back;
* the compressible laws of two elastic constants (:data:`_LAME_ENERGIES`: ``robust_neo_hookean``,
  ``stable_neo_hookean``, ``saint_venant_kirchhoff``, ``linear_elastic``, ``hencky``,
  ``saint_venant_kirchhoff_principal``, ``fixed_corotated``, ``corotational_linear``): :math:`\mu > 0` and
  :math:`K = \lambda + 2\mu/3 > 0` (so :math:`\nu \in (-1, 1/2)`), always a *compressible* fit of the full
  energy, the lateral stretch of each point solved from its traction-free faces; :math:`K` is fitted
  unless ``bulk_modulus`` is given, which needs two modes (uniaxial stress alone hardly sees
  :math:`\nu`) or volumetric data. The corotated laws take :math:`R = I`, the polar rotation of the
  diagonal :math:`F` of every mode. The table's keys are ``mu`` and ``bulk_modulus``. ``arap``
  (:math:`\mu\|F - R\|^2`, no volume term) is not fitted.

**Fixed parameters** (``fixed={"c2": 0.1}``, ``hyperfem fit --fix c2=0.1``): held at the given values (within
the law's range; the parameter class validates them with the fitted ones), the others fitted; the result lists them
(:attr:`FitResult.fixed`, a comment of the table, ``"fixed"`` of the JSON). ``initial`` only sets a start.

**Least squares.** Levenberg–Marquardt with box bounds (projected steps), the
Jacobian by forward differences of the compiled response. The residual of a
point is :math:`w_i(P^\text{fit}_i - P_i)` with :math:`w_i = 1/|P_i|` (``weighting =
"relative"``, the default, as Abaqus does: every point counts alike, not only
the largest stresses; points with :math:`P_i = 0`, or below :data:`ZERO_STRESS` of the mode's rms stress, get
that rms stress) or
:math:`w_i = 1` (``"absolute"``). The start: the law's shape at a unit shear
modulus, scaled by the one factor that fits best (the energies are linear in
their moduli).

**Result** (:class:`FitResult`): the parameters and the validated parameter
object (:attr:`FitResult.material`, e.g. a :class:`~hyperfem.materials.yeoh.YeohParameters`;
an incompressible fit gets :math:`K = 1000\mu_0` unless ``bulk_modulus`` is
given), rms, relative rms and largest relative error per mode, and Drucker's
stability (:meth:`~hyperfem.materials.homogeneous.HomogeneousResponse.drucker`)
along each fitted mode over its data range: where it is lost, mode and stretch.
"""

from __future__ import annotations

import csv
import difflib
import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any, Literal, overload

import numpy as np
import ufl

from hyperfem.errors import OutputError, ParameterError
from hyperfem.kinematics import jacobian, right_cauchy_green
from hyperfem.materials.corotational_linear import corotational_linear_energy
from hyperfem.materials.fixed_corotated import fixed_corotated
from hyperfem.materials.linear_elastic import linear_elastic
from hyperfem.materials.robust_neo_hookean import robust_neo_hookean
from hyperfem.materials.saint_venant_kirchhoff import saint_venant_kirchhoff
from hyperfem.materials.stable_neo_hookean import StableNeoHookeanParameters, stable_neo_hookean
from hyperfem.materials.principal_stretches import hencky, saint_venant_kirchhoff_principal
from hyperfem.materials.arruda_boyce import ArrudaBoyceParameters, arruda_boyce, arruda_boyce_isochoric
from hyperfem.materials.fung import FungOrthotropicParameters, fung_orthotropic_isochoric
from hyperfem.materials.gent import GentParameters, gent, gent_isochoric
from hyperfem.materials.holzapfel_gasser_ogden import (
    HolzapfelGasserOgdenParameters,
    holzapfel_gasser_ogden_isochoric,
)
from hyperfem.materials.homogeneous import MODES, Energy, HomogeneousResponse, check_mode, mode_stretches
from hyperfem.materials.mooney_rivlin import MooneyRivlinParameters, mooney_rivlin, mooney_rivlin_isochoric
from hyperfem.materials.neo_hookean import neo_hookean, neo_hookean_isochoric
from hyperfem.materials.ogden import OgdenParameters, ogden
from hyperfem.materials.parameters import LameParameters
from hyperfem.materials.principal_stretches import eigenvalue_sum
from hyperfem.materials.veronda_westmann import (
    VerondaWestmannParameters,
    veronda_westmann,
    veronda_westmann_isochoric,
)
from hyperfem.materials.weiss import WeissParameters, weiss_isochoric
from hyperfem.materials.volumetric import volumetric_energy, volumetric_law
from hyperfem.materials.yeoh import (
    ReducedPolynomialParameters,
    YeohParameters,
    reduced_polynomial,
    reduced_polynomial_isochoric,
    yeoh,
)
from hyperfem.validation import check_positive, is_finite_number

if TYPE_CHECKING:  # prony_fit imports this module's helpers: fit() imports it when called
    from hyperfem.materials.prony_fit import PronyFit

__all__ = [
    "ANGLE_COLUMN",
    "BULK_RATIO",
    "COLUMNS",
    "RELAXATION_MODE",
    "FIT_LAWS",
    "TRELOAR",
    "Curve",
    "FitResult",
    "ModeError",
    "StabilityLoss",
    "fit",
    "plot_fits",
    "read_curves",
    "relaxation_rows",
    "treloar_data",
]

Expr = ufl.core.expr.Expr

COLUMNS = ("mode", "stretch", "nominal_stress_MPa")
"""The columns :func:`read_curves` needs (module docstring)."""

ANGLE_COLUMN = "fibre_angle_deg"
"""The optional column of the fibre angle to the loading direction, in degrees (module docstring)."""

RELAXATION_MODE = "relaxation"
"""The mode of relaxation rows (with a ``time_s`` column) in a file of :func:`read_curves`: fitted by ``prony``."""

TRELOAR = Path(__file__).resolve().parent / "data" / "treloar1944.csv"
"""Treloar's 1944 data (8 % sulphur natural rubber, 20 °C): uniaxial, equibiaxial, pure shear (README beside it)."""

BULK_RATIO = 1000.0
r""":math:`K/\mu_0` of the material of an incompressible fit without ``bulk_modulus`` (:math:`\nu \approx 0.4995`)."""

WEIGHTINGS = ("relative", "absolute")

ZERO_STRESS = 1e-10
"""Stresses below this fraction of their mode's rms stress are weighted as zeros (by that rms) in relative weighting."""

_STABILITY_POINTS = 201
_CURVE_POINTS = 200


def _did_you_mean(name: str, candidates: Sequence[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest candidate (ignoring case if need be), or ``""``."""
    close = difflib.get_close_matches(name, list(candidates), n=1, cutoff=0.6)
    if not close:
        lower = {c.lower(): c for c in candidates}
        close = [lower[c] for c in difflib.get_close_matches(name.lower(), list(lower), n=1, cutoff=0.6)]
    return f" (did you mean {close[0]!r}?)" if close else ""


# -- data --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Curve:
    """The measured nominal stress of one homogeneous test mode, sorted by stretch.

    Attributes:
        mode: A mode of :data:`~hyperfem.materials.homogeneous.MODES`.
        stretch: Stretches :math:`\\lambda > 0` (dimensionless).
        stress: Nominal stresses :math:`P_{11}` (the data's unit, MPa for :func:`read_curves`).
        angle: The fibre angle in degrees (column ``fibre_angle_deg``, the fibre laws), else ``None``.
    """

    mode: str
    stretch: np.ndarray
    stress: np.ndarray
    angle: float | None = None

    @property
    def label(self) -> str:
        """The key of the curve: its mode, ``mode@angle`` with a fibre angle (``uniaxial@30``)."""
        return self.mode if self.angle is None else f"{self.mode}@{self.angle:g}"

    @property
    def angle_rad(self) -> float | None:
        """The fibre angle in radians (``None`` without)."""
        return None if self.angle is None else math.radians(self.angle)

    def __post_init__(self) -> None:
        check_mode(self.mode)
        lam = np.asarray(self.stretch, dtype=float).reshape(-1)
        P = np.asarray(self.stress, dtype=float).reshape(-1)
        if lam.size == 0 or lam.shape != P.shape:
            raise ParameterError(f"Curve {self.mode}: need as many stresses as stretches (>= 1), got "
                                 f"{lam.size} and {P.size}")
        if not (np.isfinite(lam).all() and np.isfinite(P).all() and (lam > 0).all()):
            raise ParameterError(f"Curve {self.mode}: stretches must be finite and > 0, stresses finite")
        if self.angle is not None and not (is_finite_number(self.angle) and -90.0 <= self.angle <= 90.0):
            raise ParameterError(f"Curve {self.mode}: the fibre angle must be a number of degrees in [-90, 90], "
                                 f"got {self.angle!r}")
        order = np.argsort(lam, kind="stable")
        object.__setattr__(self, "stretch", lam[order])
        object.__setattr__(self, "stress", P[order])


def _read_rows(path: str | Path, need: str) -> list[list[str]]:
    """The rows of a CSV file, its header first (``need``: the columns, for the message of an empty file).

    Raises:
        ParameterError: Missing, unreadable or empty file.
    """
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"fit: data file not found: {path}")
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ParameterError(f"fit: cannot read {path}: {exc}") from None
    if not rows:
        raise ParameterError(f"fit: {path} is empty (need a header with the columns {need})")
    return rows


def relaxation_rows(path: str | Path) -> int:
    """How many rows of mode ``relaxation`` a file of :func:`read_curves` has (0 without a ``mode`` column)."""
    rows = _read_rows(path, ", ".join(COLUMNS))
    header = [h.strip() for h in rows[0]]
    if "mode" not in header:
        return 0
    column = header.index("mode")
    return sum(1 for row in rows[1:] if len(row) > column and row[column].strip() == RELAXATION_MODE)


def read_curves(path: str | Path) -> dict[str, Curve]:
    """The curves of a CSV file of homogeneous test data (module docstring), by mode.

    Rows of mode ``relaxation`` are left out (:func:`relaxation_rows`; ``law="prony"`` fits them).

    Raises:
        ParameterError: Missing file, missing column, unknown mode, a value that is not a
            number (each naming the file and line); relaxation rows only.
    """
    path = Path(path)
    rows = _read_rows(path, ", ".join(COLUMNS))
    header = [h.strip() for h in rows[0]]
    index: dict[str, int] = {}
    for column in COLUMNS:
        if column not in header and "time_s" in header:
            raise ParameterError(f"fit: {path}: relaxation data (a column time_s): fit them with law 'prony' "
                                 f"(hyperfem fit {path.name} --law prony)")
        if column not in header:
            near = _did_you_mean(column, header) or next(
                (f" (a column {h!r}: name it {column!r})" for h in header if h.lower() == column.lower()), ""
            )
            raise ParameterError(
                f"fit: {path}: no column {column!r}{near}; the columns must include {', '.join(COLUMNS)} "
                f"(found: {', '.join(header) or 'none'})"
            )
        index[column] = header.index(column)
    angle_column = header.index(ANGLE_COLUMN) if ANGLE_COLUMN in header else None
    points: dict[tuple[str, float | None], list[tuple[float, float]]] = {}
    relaxation = 0
    for line, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        where = f"fit: {path}:{line}"
        if len(row) <= max(index.values()):
            raise ParameterError(f"{where}: {len(row)} columns, the header has {len(header)}")
        mode = row[index["mode"]].strip()
        if mode == RELAXATION_MODE:
            relaxation += 1
            continue
        if mode not in MODES:
            raise ParameterError(f"{where}: unknown mode {mode!r}{_did_you_mean(mode, [*MODES, RELAXATION_MODE])}; "
                                 f"modes: {', '.join(MODES)} ({RELAXATION_MODE}: law 'prony')")
        values = []
        for column in COLUMNS[1:]:
            text = row[index[column]].strip()
            try:
                value = float(text)
            except ValueError:
                raise ParameterError(f"{where}: {column} must be a number, got {text!r}") from None
            if not math.isfinite(value):
                raise ParameterError(f"{where}: {column} must be a finite number, got {text!r}")
            values.append(value)
        if values[0] <= 0:
            raise ParameterError(f"{where}: stretch must be > 0, got {values[0]!r}")
        angle = None
        if angle_column is not None and len(row) > angle_column and row[angle_column].strip():
            text = row[angle_column].strip()
            try:
                angle = float(text)
            except ValueError:
                raise ParameterError(f"{where}: {ANGLE_COLUMN} must be a number, got {text!r}") from None
            if not (math.isfinite(angle) and -90.0 <= angle <= 90.0):
                raise ParameterError(f"{where}: {ANGLE_COLUMN} must be in [-90, 90] degrees, got {text!r}")
        points.setdefault((mode, angle), []).append((values[0], values[1]))
    if not points and relaxation:
        raise ParameterError(f"fit: {path}: only relaxation rows (mode {RELAXATION_MODE}): fit them with law 'prony' "
                             f"(hyperfem fit {path.name} --law prony)")
    if not points:
        raise ParameterError(f"fit: {path} has no data rows")
    curves = [Curve(m, np.array([p[0] for p in v]), np.array([p[1] for p in v]), a)
              for mode in MODES for (m, a), v in points.items() if m == mode]
    return {c.label: c for c in curves}


def treloar_data() -> dict[str, Curve]:
    """Treloar's 1944 uniaxial, equibiaxial and pure-shear data (:data:`TRELOAR`), stresses in MPa."""
    return read_curves(TRELOAR)


# -- the laws ------------------------------------------------------------------------------------------
Values = Mapping[str, float]


Bounds = tuple[tuple[float, ...], tuple[float, ...]]


@dataclass(frozen=True)
class _Model:
    """What a fit needs of one law.

    ``starts`` hold the parameters for a unit shear modulus (the stress-like ones are scaled to the
    data); ``bounds(start)`` the lower and upper bounds for a start, for a unit shear modulus too.
    """

    law: str
    names: tuple[str, ...]
    stress_like: tuple[bool, ...]
    bounds: Callable[[tuple[float, ...]], Bounds]
    starts: tuple[tuple[float, ...], ...]
    isochoric: Energy | None  # None: a compressible law without an isochoric part (always fitted compressible)
    energy: Callable[[str], Energy]
    material: Callable[[Values, float, str], Any]
    keys: Callable[[Values], dict[str, float | list[float]]]
    fibres: bool = False  # the energy reads constants["fibre_angle"]: incompressible fits of curves with angles


def _fixed(lower: tuple[float, ...], upper: tuple[float, ...]) -> Callable[[tuple[float, ...]], Bounds]:
    return lambda start: (lower, upper)


def _ns(**kwargs: object) -> Any:
    """A stand-in of a parameter class holding UFL constants (the energies only read its attributes)."""
    return SimpleNamespace(**kwargs)


def _with_volume(isochoric: Energy) -> Callable[[str], Energy]:
    def energy(volumetric: str) -> Energy:
        return lambda F, c: isochoric(F, c) + volumetric_energy(jacobian(F), c["K"], volumetric)

    return energy


def _neo_hookean(terms: int, reach: float) -> _Model:
    def energy(volumetric: str) -> Energy:
        if volumetric != "log":
            raise ParameterError("fit: neo_hookean has its own volume term (hf.materials.neo_hookean); "
                                 "leave volumetric at 'log'")
        return lambda F, c: neo_hookean(F, _ns(mu=c["mu"], lmbda=c["K"] - 2.0 * c["mu"] / 3.0))

    return _Model(
        "neo_hookean", ("mu",), (True,), _fixed((1e-12,), (math.inf,)), ((1.0,),),
        lambda F, c: neo_hookean_isochoric(F, c["mu"]),
        energy,
        lambda v, K, vol: LameParameters(mu=v["mu"], lmbda=K - 2.0 * v["mu"] / 3.0),
        lambda v: {"mu": v["mu"]},
    )


def _mooney_rivlin(terms: int, reach: float) -> _Model:
    return _Model(
        "mooney_rivlin", ("c1", "c2"), (True, True), _fixed((1e-12, 0.0), (math.inf, math.inf)), ((0.4, 0.1),),
        lambda F, c: mooney_rivlin_isochoric(F, c["c1"], c["c2"]),
        lambda vol: lambda F, c: mooney_rivlin(F, _ns(c1=c["c1"], c2=c["c2"], K=c["K"], volumetric=vol)),
        lambda v, K, vol: MooneyRivlinParameters(c1=v["c1"], c2=v["c2"], K=K, volumetric=vol),
        lambda v: {"c1": v["c1"], "c2": v["c2"]},
    )


def _polynomial(law: str, terms: int) -> _Model:
    names = tuple(f"c{i}0" for i in range(1, terms + 1))

    def coefficients(c: Mapping[str, Any]) -> tuple:
        return tuple(c[n] for n in names)

    def isochoric(F: Expr, c: Mapping[str, Expr]) -> Expr:
        return reduced_polynomial_isochoric(F, _ns(coefficients=coefficients(c)))

    def energy(vol: str) -> Energy:
        return lambda F, c: reduced_polynomial(F, _ns(coefficients=coefficients(c), K=c["K"], volumetric=vol))

    def material(v: Values, K: float, vol: str) -> Any:
        if law == "yeoh":
            return YeohParameters(c10=v["c10"], c20=v["c20"], c30=v["c30"], K=K, volumetric=vol)
        return ReducedPolynomialParameters(coefficients=tuple(v[n] for n in names), K=K, volumetric=vol)

    def keys(v: Values) -> dict[str, float | list[float]]:
        if law == "yeoh":
            return {n: v[n] for n in names}
        return {"coefficients": [v[n] for n in names]}

    return _Model(
        law, names, (True,) * terms, _fixed((1e-12,) + (-math.inf,) * (terms - 1), (math.inf,) * terms),
        ((0.5,) + (0.0,) * (terms - 1),), isochoric, energy, material, keys,
    )


def _yeoh(terms: int, reach: float) -> _Model:
    return _polynomial("yeoh", 3)


def _reduced_polynomial(terms: int, reach: float) -> _Model:
    return _polynomial("reduced_polynomial", terms)


def _gent(terms: int, reach: float) -> _Model:
    def isochoric(F: Expr, c: Mapping[str, Expr]) -> Expr:
        return gent_isochoric(F, _ns(mu=c["mu"], Jm=c["Jm"], lock_fraction=None))

    return _Model(
        "gent", ("mu", "Jm"), (True, False), _fixed((1e-12, reach * (1.0 + 1e-9)), (math.inf, 1e6)),
        ((1.0, 2.0 * reach),), isochoric,
        lambda vol: lambda F, c: gent(F, _ns(mu=c["mu"], Jm=c["Jm"], K=c["K"], volumetric=vol, lock_fraction=None)),
        lambda v, K, vol: GentParameters(mu=v["mu"], Jm=v["Jm"], K=K, volumetric=vol),
        lambda v: {"mu": v["mu"], "Jm": v["Jm"]},
    )


def _arruda_boyce(terms: int, reach: float) -> _Model:
    chain = max(1.2 * math.sqrt((reach + 3.0) / 3.0), 1.5)  # above the largest chain stretch sqrt(I1bar/3)
    return _Model(
        "arruda_boyce", ("mu", "lambda_m"), (True, False), _fixed((1e-12, 1.0 + 1e-9), (math.inf, 1e3)),
        ((1.0, chain),),
        lambda F, c: arruda_boyce_isochoric(F, _ns(mu=c["mu"], lambda_m=c["lambda_m"])),
        lambda vol: lambda F, c: arruda_boyce(F, _ns(mu=c["mu"], lambda_m=c["lambda_m"], K=c["K"], volumetric=vol)),
        lambda v, K, vol: ArrudaBoyceParameters(mu=v["mu"], lambda_m=v["lambda_m"], K=K, volumetric=vol),
        lambda v: {"mu": v["mu"], "lambda_m": v["lambda_m"]},
    )


def _veronda_westmann(terms: int, reach: float) -> _Model:
    c2 = 1.0 / max(reach, 1.0)
    return _Model(
        "veronda_westmann", ("c1", "c2"), (True, False), _fixed((1e-12, 1e-9), (math.inf, 600.0 / max(reach, 1e-3))),
        ((1.0 / c2, c2),),  # mu0 = c1 c2 = 1
        lambda F, c: veronda_westmann_isochoric(F, _ns(c1=c["c1"], c2=c["c2"])),
        lambda vol: lambda F, c: veronda_westmann(F, _ns(c1=c["c1"], c2=c["c2"], K=c["K"], volumetric=vol)),
        lambda v, K, vol: VerondaWestmannParameters(c1=v["c1"], c2=v["c2"], K=K, volumetric=vol),
        lambda v: {"c1": v["c1"], "c2": v["c2"]},
    )


def _stable_constants(p: Any) -> StableNeoHookeanParameters:
    """:meth:`StableNeoHookeanParameters.from_lame` of UFL constants (its checks need numbers: skipped)."""
    constants = object.__new__(StableNeoHookeanParameters)
    object.__setattr__(constants, "mu", 4.0 * p.mu / 3.0)
    object.__setattr__(constants, "lmbda", p.lmbda + 5.0 * p.mu / 6.0)
    return constants


_LAME_ENERGIES: dict[str, Callable[[Expr, Any], Expr]] = {
    "robust_neo_hookean": robust_neo_hookean,
    "stable_neo_hookean": lambda F, p: stable_neo_hookean(F, _stable_constants(p)),
    "saint_venant_kirchhoff": saint_venant_kirchhoff,
    "linear_elastic": linear_elastic,
    "hencky": hencky,
    "saint_venant_kirchhoff_principal": saint_venant_kirchhoff_principal,
    # the polar rotation of the diagonal, positive F of every mode is I
    "fixed_corotated": lambda F, p: fixed_corotated(F, ufl.Identity(3), p),
    "corotational_linear": lambda F, p: corotational_linear_energy(F, ufl.Identity(3), p),
}
r"""The compressible laws of two elastic constants, ``psi(F, LameParameters)``, fitted as :math:`\mu` and
:math:`K = \lambda + 2\mu/3` (case-file keys ``mu``, ``bulk_modulus``)."""

_LAME_K_START = 2.0
r""":math:`K/\mu` of the start of a compressible two-constant law (:math:`\nu \approx 0.29`)."""


def _lame_law(law: str) -> Callable[[int, float], _Model]:
    energy_of = _LAME_ENERGIES[law]

    def energy(volumetric: str) -> Energy:
        if volumetric != "log":
            raise ParameterError(f"fit: {law} has its own volume term; leave volumetric at 'log'")
        return lambda F, c: energy_of(F, _ns(mu=c["mu"], lmbda=c["K"] - 2.0 * c["mu"] / 3.0))

    def factory(terms: int, reach: float) -> _Model:
        return _Model(
            law, ("mu",), (True,), _fixed((1e-12,), (math.inf,)), ((1.0,),), None, energy,
            lambda v, K, vol: LameParameters(mu=v["mu"], lmbda=K - 2.0 * v["mu"] / 3.0),
            lambda v: {"mu": v["mu"]},
        )

    return factory


_OGDEN_EXPONENTS = (1.3, 5.0, -2.0, 3.0, -4.0, 8.0, -1.0, 2.0)
_OGDEN_STARTS = {1: ((2.0,), (3.0,)), 2: ((1.3, 5.0), (2.0, -2.0), (3.0, -1.0))}


def _ogden_starts(terms: int) -> tuple[tuple[float, ...], ...]:
    """Start exponents; :math:`\\mu_p\\alpha_p/2` shares a unit shear modulus 0.9 / 0.1 / ... (the first term leads)."""
    if terms in _OGDEN_STARTS:
        patterns = _OGDEN_STARTS[terms]
    else:
        first = tuple(_OGDEN_EXPONENTS[i % len(_OGDEN_EXPONENTS)] * (1 + i // len(_OGDEN_EXPONENTS))
                      for i in range(terms))
        patterns = (first, (2.0, 4.0, -2.0, *first[3:]), (2.5, 7.0, -1.0, *first[3:]))
    starts = []
    for alpha in patterns:
        shares = [0.9] + [0.1 / (terms - 1)] * (terms - 1) if terms > 1 else [1.0]
        mu = tuple(2.0 * s / a for s, a in zip(shares, alpha, strict=True))
        starts.append(mu + tuple(alpha))
    return tuple(starts)


def _ogden(terms: int, reach: float) -> _Model:
    mu_names = tuple(f"mu_{p}" for p in range(1, terms + 1))
    alpha_names = tuple(f"alpha_{p}" for p in range(1, terms + 1))
    starts = _ogden_starts(terms)

    def isochoric(F: Expr, c: Mapping[str, Expr]) -> Expr:
        pairs = [(c[m], c[a]) for m, a in zip(mu_names, alpha_names, strict=True)]
        Cbar = jacobian(F) ** (-2.0 / 3.0) * right_cauchy_green(F)
        return eigenvalue_sum(Cbar, lambda x: sum(m / a * (x ** (0.5 * a) - 1.0) for m, a in pairs))

    def material(v: Values, K: float, vol: str) -> Any:
        return OgdenParameters(mu=tuple(v[m] for m in mu_names), alpha=tuple(v[a] for a in alpha_names), K=K,
                               volumetric=vol)

    def bounds(start: tuple[float, ...]) -> Bounds:
        """Each mu_p takes the sign of its alpha_p, kept from the start (mu_p alpha_p > 0)."""
        positive = [a > 0 for a in start[terms:]]
        lower = [1e-12 if p else -math.inf for p in positive] + [0.05 if p else -30.0 for p in positive]
        upper = [math.inf if p else -1e-12 for p in positive] + [30.0 if p else -0.05 for p in positive]
        return tuple(lower), tuple(upper)

    return _Model(
        "ogden", mu_names + alpha_names, (True,) * terms + (False,) * terms, bounds, starts,
        isochoric, _with_volume(isochoric), material,
        lambda v: {"mu": [v[m] for m in mu_names], "alpha": [v[a] for a in alpha_names]},
    )


def _hgo_directions(c: Mapping[str, Any]) -> tuple[Expr, Expr]:
    """HGO's two families at +-theta to e1 in the e1-e2 plane."""
    theta = c["fibre_angle"]
    return (ufl.as_vector([ufl.cos(theta), ufl.sin(theta), 0.0]),
            ufl.as_vector([ufl.cos(theta), -ufl.sin(theta), 0.0]))


def _holzapfel_gasser_ogden(terms: int, reach: float) -> _Model:
    def isochoric(F: Expr, c: Mapping[str, Any]) -> Expr:
        a1, a2 = _hgo_directions(c)
        return holzapfel_gasser_ogden_isochoric(
            F, a1, a2, _ns(mu=c["mu"], k1=c["k1"], k2=c["k2"], kappa=c["kappa"], switch="strain", smoothing=0.0))

    def energy(vol: str) -> Energy:
        raise ParameterError("fit: holzapfel_gasser_ogden is fitted incompressible (no bulk_modulus, no volumetric "
                             "data)")

    return _Model(
        "holzapfel_gasser_ogden", ("mu", "k1", "k2", "kappa"), (True, True, False, False),
        _fixed((1e-12, 0.0, 1e-6, 0.0), (math.inf, math.inf, 1e3, 1.0 / 3.0)),
        ((1.0, 5.0, 1.0, 0.1), (1.0, 20.0, 5.0, 0.0), (1.0, 1.0, 0.2, 0.2)),
        isochoric, energy,
        lambda v, K, vol: HolzapfelGasserOgdenParameters(mu=v["mu"], k1=v["k1"], k2=v["k2"], kappa=v["kappa"],
                                                         K=K, volumetric=vol),
        lambda v: {"mu": v["mu"], "k1": v["k1"], "k2": v["k2"], "kappa": v["kappa"]},
        fibres=True,
    )


_WEISS_POINTS = 64
"""Gauss-Legendre points of Weiss's toe integral in a fit (the most the law takes: its own count depends on c4 and
lambda_star, which are constants here)."""


def _weiss(terms: int, reach: float) -> _Model:
    def isochoric(F: Expr, c: Mapping[str, Any]) -> Expr:
        theta = c["fibre_angle"]
        a0 = ufl.as_vector([ufl.cos(theta), ufl.sin(theta), 0.0])
        c3, c4, c5, ls = c["c3"], c["c4"], c["c5"], c["lambda_star"]
        params = _ns(c1=c["c1"], c2=c["c2"], c3=c3, c4=c4, c5=c5, lambda_star=ls,
                     c6=c3 * (ufl.exp(c4 * (ls - 1.0)) - 1.0) - c5 * ls, quadrature_points=_WEISS_POINTS)
        return weiss_isochoric(F, a0, params)

    def energy(vol: str) -> Energy:
        raise ParameterError("fit: weiss is fitted incompressible (no bulk_modulus, no volumetric data)")

    return _Model(
        "weiss", ("c1", "c2", "c3", "c4", "c5", "lambda_star"), (True, True, True, False, True, False),
        _fixed((1e-12, 0.0, 0.0, 1e-3, 0.0, 1.0 + 1e-6), (math.inf, math.inf, math.inf, 500.0, math.inf, 2.0)),
        ((0.5, 0.0, 0.2, 40.0, 300.0, 1.06), (0.5, 0.0, 1.0, 10.0, 50.0, 1.15)),
        isochoric, energy,
        lambda v, K, vol: WeissParameters(c1=v["c1"], c2=v["c2"], c3=v["c3"], c4=v["c4"], c5=v["c5"],
                                          lambda_star=v["lambda_star"], K=K, volumetric=vol),
        lambda v: {k: v[k] for k in ("c1", "c2", "c3", "c4", "c5", "lambda_star")},
        fibres=True,
    )


_FUNG_NAMES = ("c", "b1", "b2", "b3", "b4", "b5", "b6", "b7", "b8", "b9")
_FUNG_SHEAR = ("b7", "b8", "b9")
"""Fung's in-plane shear constants: no test along the material axes strains E12, E23, E31, so ``fixed`` gives them."""


def _fung_orthotropic(terms: int, reach: float) -> _Model:
    def isochoric(F: Expr, c: Mapping[str, Any]) -> Expr:
        theta = c["fibre_angle"]
        a1 = ufl.as_vector([ufl.cos(theta), ufl.sin(theta), 0.0])
        a2 = ufl.as_vector([-ufl.sin(theta), ufl.cos(theta), 0.0])
        b = {n: c[n] for n in _FUNG_NAMES}
        params = _ns(c=b["c"], b7=b["b7"], b8=b["b8"], b9=b["b9"],
                     normal_block=((b["b1"], b["b4"], b["b6"]), (b["b4"], b["b2"], b["b5"]),
                                   (b["b6"], b["b5"], b["b3"])))
        return fung_orthotropic_isochoric(F, a1, a2, params)

    def energy(vol: str) -> Energy:
        raise ParameterError("fit: fung_orthotropic is fitted incompressible (no bulk_modulus, no volumetric data)")

    return _Model(
        "fung_orthotropic", _FUNG_NAMES, (True,) + (False,) * 9,
        _fixed((1e-12, 1e-6, 1e-6, 1e-6, -1e3, -1e3, -1e3, 1e-6, 1e-6, 1e-6),
               (math.inf, 1e3, 1e3, 1e3, 1e3, 1e3, 1e3, 1e3, 1e3, 1e3)),
        ((1.0, 5.0, 5.0, 5.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0), (1.0, 20.0, 10.0, 10.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0),
         (1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0)),
        isochoric, energy,
        lambda v, K, vol: FungOrthotropicParameters(**{n: v[n] for n in _FUNG_NAMES}, K=K, volumetric=vol),
        lambda v: {n: v[n] for n in _FUNG_NAMES},
        fibres=True,
    )


_FIBRE_TABLES = {"holzapfel_gasser_ogden": "hgo", "weiss": "one", "fung_orthotropic": "axes"}
"""The fitted fibre laws and their [fibres] tables (``hgo``: two families at +-theta; ``one``: one family at theta,
only along or across the load: at another angle a test of one family shears; ``axes``: the orthotropic axes a1 at
theta, a2 across it in the 1-2 plane, along or across the load only: at another angle an orthotropic test shears)."""
_REQUIRED_FIXED = {"fung_orthotropic": _FUNG_SHEAR}
"""Parameters no homogeneous test of :func:`fit` strains, which ``fixed`` must give."""

_MODELS: dict[str, Callable[[int, float], _Model]] = {
    "neo_hookean": _neo_hookean,
    "mooney_rivlin": _mooney_rivlin,
    "yeoh": _yeoh,
    "reduced_polynomial": _reduced_polynomial,
    "gent": _gent,
    "arruda_boyce": _arruda_boyce,
    "veronda_westmann": _veronda_westmann,
    "ogden": _ogden,
    **{law: _lame_law(law) for law in _LAME_ENERGIES},
    "holzapfel_gasser_ogden": _holzapfel_gasser_ogden,
    "weiss": _weiss,
    "fung_orthotropic": _fung_orthotropic,
}
FIT_LAWS: tuple[str, ...] = (*_MODELS, "prony")
"""The laws :func:`fit` knows (their case-file names; ``prony``: a Prony series to relaxation data)."""

_NOT_FITTED = {
    "muscle": "its active part is not a property of passive tests",
    "arap": "mu |F - R|^2 has no volume term (one constant, lateral stretch 1): fit linear_elastic or "
            "fixed_corotated and keep mu",
}
"""Case-file laws :func:`fit` does not fit, and why (their error names the reason, not an unknown law)."""

_TERMS = {"reduced_polynomial": 3, "ogden": 3}
"""Laws with a number of terms, and its default."""


# -- least squares -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Solution:
    x: np.ndarray
    cost: float
    iterations: int
    converged: bool


def _least_squares(
    residual: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    typical: np.ndarray,
    max_iterations: int,
) -> _Solution:
    """Levenberg–Marquardt (Marquardt's diagonal scaling) with steps projected onto the bounds."""

    def cost_of(r: np.ndarray) -> float:
        return 0.5 * float(r @ r) if np.isfinite(r).all() else math.inf

    x = np.clip(x0, lower, upper)
    r = residual(x)
    cost = cost_of(r)
    if not math.isfinite(cost):
        raise ParameterError("fit: the start gives no finite stress at the data; give another start (initial)")
    damping = 1e-3
    for iteration in range(1, max_iterations + 1):
        J = np.empty((r.size, x.size))
        for k in range(x.size):
            h = 1e-7 * max(abs(x[k]), typical[k])
            if x[k] + h > upper[k]:
                h = -h
            step = x.copy()
            step[k] += h
            J[:, k] = (residual(step) - r) / h
        if not np.isfinite(J).all():
            J = np.where(np.isfinite(J), J, 0.0)
        A, g = J.T @ J, J.T @ r
        diagonal = np.maximum(np.diag(A), 1e-30 * max(float(np.diag(A).max()), 1e-300))
        while True:
            try:
                dx = np.linalg.solve(A + damping * np.diag(diagonal), -g)
            except np.linalg.LinAlgError:
                dx = np.full_like(x, np.nan)
            trial = np.clip(x + dx, lower, upper)
            r_trial = residual(trial) if np.isfinite(trial).all() else np.full_like(r, np.nan)
            cost_trial = cost_of(r_trial)
            if cost_trial < cost:
                break
            damping *= 4.0
            if damping > 1e12:
                return _Solution(x, cost, iteration, True)  # no descent left: a minimum (or at a bound)
        decrease = (cost - cost_trial) / max(cost, 1e-300)
        moved = float(np.max(np.abs(trial - x) / np.maximum(np.abs(x), typical)))
        x, r, cost = trial, r_trial, cost_trial
        damping = max(damping / 3.0, 1e-12)
        if decrease < 1e-12 or moved < 1e-12 or cost == 0.0:
            return _Solution(x, cost, iteration, True)
    return _Solution(x, cost, max_iterations, False)


@functools.lru_cache(maxsize=32)
def _response(law: str, terms: int, incompressible: bool, volumetric: str) -> HomogeneousResponse:
    """The compiled response of a law (the isochoric part, or the full energy with ``K`` last), kept for reuse."""
    model = _MODELS[law](terms, 1.0)
    if incompressible:
        assert model.isochoric is not None  # fit() fits a law without an isochoric part compressible
        return HomogeneousResponse(model.isochoric, model.names, incompressible=True, fibres=model.fibres)
    return HomogeneousResponse(model.energy(volumetric), (*model.names, "K"), incompressible=False)


# -- the result ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ModeError:
    """How far a fit is from one mode's data.

    Attributes:
        points: Number of data points.
        rms: Root mean square of :math:`P^\\text{fit} - P` (stress unit of the data).
        relative_rms: Root mean square of :math:`(P^\\text{fit} - P)/P` over the points with :math:`P \\ne 0`.
        max_relative: Largest :math:`|P^\\text{fit} - P|/|P|` over those points.
    """

    points: int
    rms: float
    relative_rms: float
    max_relative: float


@dataclass(frozen=True)
class StabilityLoss:
    """Where a fitted law loses Drucker stability along one mode: the stretch nearest 1 on one side of 1.

    Attributes:
        mode: The mode.
        stretch: The first stretch (of a grid of 201 over the data range) with a non-positive
            (or non-finite) smallest eigenvalue, going away from 1.
    """

    mode: str
    stretch: float


@dataclass(frozen=True, eq=False)
class FitResult:
    """The fitted law: parameters, errors per mode, stability, and the curves to plot.

    Attributes:
        law: Case-file name of the law.
        terms: Number of terms (``ogden``, ``reduced_polynomial``), else ``None``.
        parameters: Fitted values by name (``mu_1, ..., alpha_1, ...`` for Ogden), data stress unit;
            ``K`` among them for a compressible fit with volumetric data.
        material: The validated parameter object of the law (bulk modulus :attr:`bulk_modulus`).
        incompressible: Whether the fit assumed incompressibility.
        bulk_modulus: The material's :math:`K`: fitted, given, or :data:`BULK_RATIO` times :math:`\\mu_0`.
        volumetric: Volumetric law of the material.
        weighting: ``"relative"`` or ``"absolute"``.
        data: The fitted curves by mode.
        model: The fitted law's stress at the data stretches, by mode.
        errors: :class:`ModeError` by mode.
        stability_lost: Where Drucker stability is lost (empty: stable over the data range).
        curves: ``(stretch, stress)`` of the fitted law on a fine grid over each mode's range.
        iterations: Levenberg–Marquardt iterations (of the best start).
        converged: Whether the optimiser stopped at a minimum.
        fixed: The parameters held at given values (``fit(fixed=...)``), not fitted; in :attr:`parameters` too.
    """

    law: str
    terms: int | None
    parameters: dict[str, float]
    material: Any
    incompressible: bool
    bulk_modulus: float
    volumetric: str
    weighting: str
    data: dict[str, Curve]
    model: dict[str, np.ndarray]
    errors: dict[str, ModeError]
    stability_lost: tuple[StabilityLoss, ...]
    curves: dict[str, tuple[np.ndarray, np.ndarray]] = field(repr=False)
    iterations: int
    converged: bool
    fixed: tuple[str, ...] = ()

    @property
    def stable(self) -> bool:
        """Whether the law is Drucker stable along every fitted mode over its data range."""
        return not self.stability_lost

    @property
    def label(self) -> str:
        """``law`` with its number of terms, e.g. ``ogden (3 terms)``."""
        return self.law if self.terms is None else f"{self.law} ({self.terms} terms)"

    def material_with(self, bulk_modulus: float | None = None) -> Any:
        """The parameter object of the fitted law with another bulk modulus (default :attr:`bulk_modulus`)."""
        if bulk_modulus is None:
            return self.material
        check_positive("bulk_modulus", bulk_modulus, "FitResult.material_with")
        values = {k: v for k, v in self.parameters.items() if k != "K"}
        return _MODELS[self.law](self.terms or 1, 1.0).material(values, float(bulk_modulus), self.volumetric)

    def energy(self, F: Expr, bulk_modulus: float | None = None) -> Expr:
        """The fitted law's full strain energy :math:`\\psi(F)`, bulk modulus :attr:`bulk_modulus` or the one given."""
        laws: dict[str, Callable[[Expr, Any], Expr]] = {
            "neo_hookean": neo_hookean, "mooney_rivlin": mooney_rivlin, "yeoh": yeoh,
            "reduced_polynomial": reduced_polynomial, "gent": gent, "arruda_boyce": arruda_boyce,
            "veronda_westmann": veronda_westmann, "ogden": ogden,
            **{k: v for k, v in _LAME_ENERGIES.items() if k not in ("fixed_corotated", "corotational_linear")},
        }
        if self.law in _FIBRE_TABLES:
            raise ParameterError(f"FitResult.energy: {self.law} needs its fibre directions: "
                                 f"hf.materials.{self.law}(F, <directions>, result.material)")
        if self.law not in laws:  # the energy of a diagonal F takes R = I, not a finite-element model's
            raise ParameterError(f"FitResult.energy: {self.law} needs the polar rotation of F: build it from "
                                 "the fitted material (hf.materials.FixedCorotated / corotational_linear)")
        return laws[self.law](F, self.material_with(bulk_modulus))

    def nominal_stress(self, mode: str, stretch: Sequence[float] | np.ndarray,
                       bulk_modulus: float | None = None, angle: float | None = None) -> np.ndarray:
        """The fitted law's nominal stress :math:`P_{11}` along ``mode``.

        Args:
            mode: A mode of :data:`~hyperfem.materials.homogeneous.MODES`.
            stretch: Test stretches.
            bulk_modulus: ``None``: the response as fitted (incompressible, or compressible with the
                fitted or given K); a number: the compressible law with this K (what a finite-element
                model of :meth:`energy` with it gives).
            angle: The fibre angle in degrees (the fibre laws).
        """
        compressible = bulk_modulus is not None or not self.incompressible
        response = _response(self.law, self.terms or 1, not compressible, self.volumetric)
        values = [v for k, v in self.parameters.items() if k != "K"]
        if compressible:
            values.append(self.bulk_modulus if bulk_modulus is None else float(bulk_modulus))
        response.set_parameters(values)
        with np.errstate(all="ignore"):
            return response.nominal_stress(mode, stretch, None if angle is None else math.radians(angle))

    def keys(self) -> dict[str, float | list[float] | str]:
        """The law's own keys of a case-file ``[[material]]`` with the fitted values (data stress unit), K included."""
        model = _MODELS[self.law](self.terms or 1, 1.0)
        keys: dict[str, float | list[float] | str] = dict(model.keys(self.parameters))
        keys["bulk_modulus" if self.law == "neo_hookean" or self.law in _LAME_ENERGIES else "K"] = self.bulk_modulus
        if self.volumetric != "log":
            keys["volumetric"] = self.volumetric
        return keys

    def case_table(self, stress_factor: float = 1.0, unit: str = "Pa") -> str:
        """A ``[[material]]`` table with the fitted values, to paste into a case file.

        Args:
            stress_factor: Multiplies the moduli (1e6: data in MPa, case file in Pa).
            unit: Name of the resulting stress unit, for the comment.
        """
        check_positive("stress_factor", stress_factor, "FitResult.case_table")
        dimensionless = ({"Jm", "lambda_m", "alpha"} | ({"c2"} if self.law == "veronda_westmann" else set())
                         | ({"k2", "kappa"} if self.law == "holzapfel_gasser_ogden" else set())
                         | ({"c4", "lambda_star"} if self.law == "weiss" else set())
                         | (set(_FUNG_NAMES[1:]) if self.law == "fung_orthotropic" else set()))
        kind = "incompressible" if self.incompressible else "compressible"
        lines = [f"# {self.label} fitted to {', '.join(self.data)} ({kind}, {self.weighting} least squares); "
                 f"moduli in {unit}"]
        if self.fixed:
            lines.append(f"# fixed, not fitted: {', '.join(self.fixed)}")
        if self.incompressible:
            lines.append(f"# K = {BULK_RATIO:g} mu0, not fitted: nearly incompressible, use [problem] "
                         'formulation = "mixed"')
        lines += ["[[material]]", f'law = "{self.law}"']
        for key, value in self.keys().items():
            scale = 1.0 if key in dimensionless or key == "volumetric" else stress_factor
            if isinstance(value, str):
                lines.append(f'{key} = "{value}"')
            elif isinstance(value, list):
                lines.append(f"{key} = [{', '.join(_number(v * scale) for v in value)}]")
            else:
                lines.append(f"{key} = {_number(value * scale)}")
        if self.law in _FIBRE_TABLES:
            angles = sorted({c.angle for c in self.data.values() if c.angle is not None})
            theta = math.radians(angles[0])
            kind = _FIBRE_TABLES[self.law]
            lines += [f"# the fibres of a specimen with {ANGLE_COLUMN} = {angles[0]:g} (fitted: "
                      f"{', '.join(f'{a:g}' for a in angles)}); "
                      + ("the two families at +-theta to x in the x-y plane: " if kind == "hgo" else
                         "the material axes a1 at theta to x, a2 across it in the x-y plane: " if kind == "axes"
                         else "")
                      + "set them to your geometry's", "[fibres]", 'type = "constant"',
                      f"direction = [{_number(math.cos(theta))}, {_number(math.sin(theta))}, 0.0]"]
            if kind != "one":
                second = ((math.cos(theta), -math.sin(theta) + 0.0) if kind == "hgo" else
                          (-math.sin(theta) + 0.0, math.cos(theta)))
                lines += ["[second_fibres]", 'type = "constant"',
                          f"direction = [{_number(second[0])}, {_number(second[1])}, 0.0]"]
        return "\n".join(lines) + "\n"

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready summary: law, parameters (structured as the case-file keys, data unit), errors, stability."""
        keys = self.keys()
        if "K" not in self.parameters:
            keys.pop("K", None)
            keys.pop("bulk_modulus", None)
        keys.pop("volumetric", None)
        return {
            "law": self.law,
            "terms": self.terms,
            "incompressible": self.incompressible,
            "parameters": keys,
            "fixed": list(self.fixed),
            "bulk_modulus_MPa": self.bulk_modulus,
            "rms_MPa": {m: e.rms for m, e in self.errors.items()},
            "relative_rms": {m: e.relative_rms for m, e in self.errors.items()},
            "max_relative": {m: e.max_relative for m, e in self.errors.items()},
            "stable": self.stable,
            "stability_lost": [{"mode": s.mode, "stretch": s.stretch} for s in self.stability_lost],
            "weighting": self.weighting,
            "converged": self.converged,
            "iterations": self.iterations,
        }

    def summary(self, unit: str = "MPa") -> str:
        """Parameters, errors per mode and stability as text."""
        kind = "incompressible" if self.incompressible else f"compressible, K = {self.bulk_modulus:.6g} {unit}"
        state = ("parameters as given, not fitted" if self.iterations == 0 else
                 f"{'converged' if self.converged else 'NOT converged'} in {self.iterations} iterations")
        lines = [f"{self.label}, {kind}, {self.weighting} least squares ({state})"]
        lines += [f"  {name:<10} {value: .6g}" + ("  (fixed)" if name in self.fixed else "")
                  for name, value in self.parameters.items()]
        w = max([12, *(len(m) for m in self.errors)])
        lines.append(f"  {'mode':<{w}} {'points':>6} {'rms [' + unit + ']':>12} {'rel. rms':>9} {'max rel.':>9}")
        for mode, e in self.errors.items():
            lines.append(f"  {mode:<{w}} {e.points:>6} {e.rms:>12.4g} {e.relative_rms:>9.2%} {e.max_relative:>9.2%}")
        lines.append("  Drucker stable over the data range" if self.stable else
                     "  Drucker stability lost: " + ", ".join(f"{s.mode} at stretch {s.stretch:.4g}"
                                                              for s in self.stability_lost))
        return "\n".join(lines)


def _number(value: float) -> str:
    """A TOML float with 6 significant digits (``2.0``, ``1.5e-05``)."""
    text = f"{value:.6g}"
    return text if any(c in text for c in ".en") else text + ".0"


# -- the fit ---------------------------------------------------------------------------------------------
def _select(data: object, modes: Sequence[str] | None, law: str) -> dict[str, Curve]:
    curves: dict[str, Any]
    if isinstance(data, (str, Path)):
        curves = dict(read_curves(data))
    elif isinstance(data, Mapping):
        curves = dict(data)
    elif isinstance(data, Sequence) and all(isinstance(c, Curve) for c in data):
        curves = {c.label: c for c in data}
    else:
        raise ParameterError(f"fit: data must be curves by mode, a sequence of Curve or a CSV path, got "
                             f"{type(data).__name__} (relaxation data: law 'prony')")
    for name, curve in curves.items():
        if not isinstance(curve, Curve) or curve.label != name:
            raise ParameterError(f"fit: data must map each mode (mode@angle with a fibre angle) to its Curve, got "
                                 f"{name!r}: {curve!r}")
    if modes is None:
        return curves
    if isinstance(modes, str):
        modes = [modes]
    selected = {}
    for mode in modes:
        if mode == RELAXATION_MODE:
            raise ParameterError(f"fit: relaxation data are fitted by law 'prony' (a Prony series), not by {law}")
        if mode not in MODES:
            raise ParameterError(f"fit: unknown mode {mode!r}{_did_you_mean(str(mode), list(MODES))}; "
                                 f"modes: {', '.join(MODES)}")
        chosen = {k: c for k, c in curves.items() if c.mode == mode}
        if not chosen:
            raise ParameterError(f"fit: no {mode} data (the data have {', '.join(curves)})")
        selected.update(chosen)
    if not selected:
        raise ParameterError("fit: no mode selected")
    return selected


def _reach(curves: Mapping[str, Curve]) -> float:
    r"""The largest :math:`\bar I_1 - 3` of the data (incompressible kinematics)."""
    reach = 0.0
    for curve in curves.values():
        if curve.mode in ("uniaxial", "equibiaxial", "pure_shear"):
            reach = max(reach, float(np.max(np.sum(mode_stretches(curve.mode, curve.stretch) ** 2, axis=1) - 3.0)))
    return reach


def _weights(curves: Mapping[str, Curve], weighting: str) -> np.ndarray:
    out = []
    for curve in curves.values():
        P = np.abs(curve.stress)
        if weighting == "absolute":
            out.append(np.ones_like(P))
            continue
        floor = float(np.sqrt(np.mean(P**2))) or 1.0
        # A stress of round-off size (data generated at lambda = 1: 1e-16 for 0) counts as 0, not as a weight of 1e16.
        out.append(1.0 / np.where(P > ZERO_STRESS * floor, P, floor))
    return np.concatenate(out)


def _mode_error(curve: Curve, model: np.ndarray) -> ModeError:
    diff = model - curve.stress
    nonzero = curve.stress != 0.0
    relative = np.abs(diff[nonzero] / curve.stress[nonzero]) if nonzero.any() else np.zeros(1)
    return ModeError(
        points=int(curve.stretch.size),
        rms=float(np.sqrt(np.mean(diff**2))),
        relative_rms=float(np.sqrt(np.mean(relative**2))),
        max_relative=float(np.max(relative)),
    )


def _stability_and_curves(
    response: HomogeneousResponse, curves: Mapping[str, Curve]
) -> tuple[tuple[StabilityLoss, ...], dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Drucker's check along each mode over its data range (1 included), and the fitted curve there."""
    lost: list[StabilityLoss] = []
    smooth: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    with np.errstate(all="ignore"):
        for mode, curve in curves.items():  # mode: the curve's label
            first, last = min(1.0, float(curve.stretch[0])), max(1.0, float(curve.stretch[-1]))
            grid = np.unique(np.concatenate([np.linspace(first, last, _STABILITY_POINTS), [1.0]]))
            # NaN: no finite stress, not stable either
            bad = ~(response.drucker(curve.mode, grid, curve.angle_rad) > 0.0)
            for side in (grid > 1.0, grid < 1.0):
                where = np.flatnonzero(bad & side)
                if where.size:
                    lost.append(StabilityLoss(mode, float(grid[where[np.argmin(np.abs(grid[where] - 1.0))]])))
            stretch = np.linspace(first, last, _CURVE_POINTS)
            smooth[mode] = (stretch, response.nominal_stress(curve.mode, stretch, curve.angle_rad))
    return tuple(lost), smooth


@overload
def fit(
    law: Literal["prony"],
    data: Any,
    *,
    terms: int | None = None,
    modes: Sequence[str] | None = None,
    bulk_modulus: float | None = None,
    volumetric: str = "log",
    weighting: str = "relative",
    initial: Mapping[str, float] | None = None,
    fixed: Mapping[str, float] | None = None,
    max_iterations: int | None = None,
    tau: Sequence[float] | None = None,
    fit_tau: bool | None = None,
    ramp_time: float | None = None,
) -> PronyFit: ...


@overload
def fit(
    law: str,
    data: Mapping[str, Curve] | Sequence[Curve] | str | Path,
    *,
    terms: int | None = None,
    modes: Sequence[str] | None = None,
    bulk_modulus: float | None = None,
    volumetric: str = "log",
    weighting: str = "relative",
    initial: Mapping[str, float] | None = None,
    fixed: Mapping[str, float] | None = None,
    max_iterations: int | None = None,
    tau: Sequence[float] | None = None,
    fit_tau: bool | None = None,
    ramp_time: float | None = None,
) -> FitResult: ...


def fit(
    law: str,
    data: Any,
    *,
    terms: int | None = None,
    modes: Sequence[str] | None = None,
    bulk_modulus: float | None = None,
    volumetric: str = "log",
    weighting: str = "relative",
    initial: Mapping[str, float] | None = None,
    fixed: Mapping[str, float] | None = None,
    max_iterations: int | None = None,
    tau: Sequence[float] | None = None,
    fit_tau: bool | None = None,
    ramp_time: float | None = None,
) -> FitResult | PronyFit:
    """Least-squares fit of a law's parameters to homogeneous test data (module docstring).

    ``law="prony"`` fits a Prony series to relaxation data instead: it is
    :func:`~hyperfem.materials.prony_fit.fit_prony` (``data`` a
    :class:`~hyperfem.materials.prony_fit.RelaxationCurve` or its CSV path; ``terms``, ``tau``,
    ``fit_tau``, ``ramp_time``, ``weighting``, ``max_iterations``), returning a
    :class:`~hyperfem.materials.prony_fit.PronyFit`.

    Args:
        law: One of :data:`FIT_LAWS`.
        data: Curves by mode (:func:`read_curves`), a sequence of :class:`Curve`, or a CSV path
            (``prony``: relaxation data).
        terms: Number of terms of ``ogden`` and ``reduced_polynomial`` (default 3).
        modes: The modes to fit (default: every mode of the data).
        bulk_modulus: Fixed :math:`K` (data stress unit): a compressible fit. Without it the fit
            is incompressible, unless the data include ``volumetric``, which fits :math:`K`.
        volumetric: The volumetric law :math:`U(J)` of a compressible fit and of the material.
        weighting: ``"relative"`` (default) or ``"absolute"`` residuals.
        initial: Start values by parameter name (those not given: the default start); one start only.
        fixed: Parameters held at the given values by name (data stress unit), the others fitted; the values
            must lie in the law's range and the parameter class validates them with the fitted ones; the result
            holds them (:attr:`FitResult.fixed`, the table and the JSON). ``fung_orthotropic`` needs its shear
            constants ``b7, b8, b9`` here (no test along the material axes strains them).
        max_iterations: Levenberg–Marquardt iterations per start (default 500; ``prony``: 200); 0
            evaluates the start (e.g. published parameters given as ``initial``) without fitting.
        tau: ``prony`` only: given relaxation times (s).
        fit_tau: ``prony`` only: fit the relaxation times (default: when ``tau`` is not given).
        ramp_time: ``prony`` only: the ramp duration of a CSV path (s).

    Returns:
        The :class:`FitResult` (``prony``: a :class:`~hyperfem.materials.prony_fit.PronyFit`).

    Raises:
        ParameterError: Unknown law, mode or weighting, terms for a law without terms, a compressible
            fit without K or volumetric data, volumetric data in an incompressible fit, an unknown or
            out-of-range fixed parameter, a law's required fixed parameter missing.
    """
    if law == "prony":
        from hyperfem.materials.prony_fit import fit_prony

        elastic_only = {"modes": modes, "bulk_modulus": bulk_modulus, "initial": initial, "fixed": fixed,
                        "volumetric": None if volumetric == "log" else volumetric}
        given = [k for k, v in elastic_only.items() if v is not None]
        if given:
            raise ParameterError(f"fit: {given[0]} is an option of the hyperelastic laws, not of prony "
                                 "(relaxation data: terms, tau, fit_tau, ramp_time, weighting)")
        if isinstance(data, Mapping) or (isinstance(data, Sequence) and not isinstance(data, str)):
            raise ParameterError("fit: prony fits relaxation data (a RelaxationCurve or a CSV with time_s), "
                                 "not hyperelastic curves")
        return fit_prony(data, terms=terms, tau=tau, fit_tau=fit_tau, ramp_time=ramp_time, weighting=weighting,
                         max_iterations=200 if max_iterations is None else max_iterations)
    relaxation_only = {"tau": tau, "fit_tau": fit_tau, "ramp_time": ramp_time}
    given = [k for k, v in relaxation_only.items() if v is not None]
    if given and law in _MODELS:
        raise ParameterError(f"fit: {given[0]} is an option of law 'prony' (relaxation data), not of {law}")
    if max_iterations is None:
        max_iterations = 500
    if law in _NOT_FITTED:
        raise ParameterError(f"fit: law {law!r} is not fitted to test data ({_NOT_FITTED[law]}); "
                             f"laws: {', '.join(FIT_LAWS)}")
    if law not in _MODELS:
        raise ParameterError(f"fit: unknown law {law!r}{_did_you_mean(str(law), FIT_LAWS)}; "
                             f"laws: {', '.join(FIT_LAWS)}")
    if terms is not None and law not in _TERMS:
        raise ParameterError(f"fit: law {law!r} has no terms to choose (only {', '.join(_TERMS)} take terms)")
    if terms is not None and (not isinstance(terms, int) or isinstance(terms, bool) or not 1 <= terms <= 8):
        raise ParameterError(f"fit: terms must be an integer from 1 to 8, got {terms!r}")
    if weighting not in WEIGHTINGS:
        raise ParameterError(f"fit: weighting must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
    volumetric_law(volumetric)
    if bulk_modulus is not None:
        check_positive("bulk_modulus", bulk_modulus, "fit")
    n_terms = terms if terms is not None else _TERMS.get(law)
    curves = _select(data, modes, law)
    model = _MODELS[law](n_terms or 1, _reach(curves))
    compressible_only = model.isochoric is None
    angled = [k for k, c in curves.items() if c.angle is not None]
    if model.fibres:
        plain = [k for k, c in curves.items() if c.angle is None]
        if plain:
            raise ParameterError(f"fit: {law} needs the fibre angle of every curve (a column {ANGLE_COLUMN}); "
                                 f"{plain[0]} has none")
        if bulk_modulus is not None or any(c.mode == "volumetric" for c in curves.values()):
            raise ParameterError(f"fit: {law} is fitted incompressible (no bulk_modulus, no volumetric data)")
        skew = [k for k, c in curves.items() if _FIBRE_TABLES[law] in ("one", "axes")
                and abs(c.angle or 0.0) not in (0.0, 90.0)]
        if skew:
            what = "has one fibre family" if _FIBRE_TABLES[law] == "one" else "is orthotropic"
            raise ParameterError(f"fit: {law} {what}: a test at fibre angle {skew[0]} shears, which "
                                 "these homogeneous modes do not; angles 0 (along the load) or 90 (across) only")
    elif angled:
        raise ParameterError(f"fit: {law} is isotropic: the fibre angle ({ANGLE_COLUMN}, {angled[0]}) is for "
                             f"the fibre law holzapfel_gasser_ogden")
    has_volumetric = any(c.mode == "volumetric" for c in curves.values())
    fit_K = (has_volumetric or compressible_only) and bulk_modulus is None
    incompressible = bulk_modulus is None and not fit_K
    if compressible_only and fit_K and len(curves) == 1 and not has_volumetric:
        raise ParameterError(f"fit: {law} is compressible and one {next(iter(curves))} curve does not determine "
                             "both mu and the bulk modulus: add a second mode (volumetric, equibiaxial, "
                             "pure_shear, uniaxial) or give bulk_modulus")

    names = model.names + (("K",) if fit_K else ())
    stress_like = np.array(model.stress_like + ((True,) if fit_K else ()))
    k_start = _LAME_K_START if compressible_only else 100.0
    starts = [s + ((k_start,) if fit_K else ()) for s in model.starts]
    held = _held(law, names, fixed)
    start_values = {k: float(v) for k, v in (initial or {}).items()}
    unknown = [k for k in start_values if k not in names]
    if unknown:
        raise ParameterError(f"fit: {law} has no parameter {unknown[0]!r}{_did_you_mean(unknown[0], names)}; "
                             f"parameters: {', '.join(names)}")
    if start_values:
        starts = [tuple(start_values.get(n, v) for n, v in zip(names, starts[0], strict=True))]
    start_values.update(held)
    starts = [tuple(held.get(n, v) for n, v in zip(names, s, strict=True)) for s in starts]
    free = np.array([n not in held for n in names])

    response = _response(law, n_terms or 1, incompressible, volumetric)
    K_fixed = bulk_modulus

    def evaluate(x: np.ndarray) -> dict[str, np.ndarray]:
        response.set_parameters([*x, K_fixed] if K_fixed is not None else x)
        with np.errstate(all="ignore"):
            return {key: response.nominal_stress(c.mode, c.stretch, c.angle_rad) for key, c in curves.items()}

    target = np.concatenate([c.stress for c in curves.values()])
    weights = _weights(curves, weighting)

    def residual(x: np.ndarray) -> np.ndarray:
        return weights * (np.concatenate(list(evaluate(x).values())) - target)

    def full(x0: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        """The parameters of the free values ``y`` (the held ones from ``x0``)."""
        def expand(y: np.ndarray) -> np.ndarray:
            x = x0.copy()
            x[free] = y
            return x
        return expand

    best: _Solution | None = None
    for start in starts:
        low, high = model.bounds(start[: len(model.names)])
        lower = np.array(low + ((1e-12,) if fit_K else ()))
        upper = np.array(high + ((math.inf,) if fit_K else ()))
        outside = [n for n, v, lo, hi in zip(names, start, lower, upper, strict=True)
                   if n in held and not lo <= v <= hi]
        if outside:
            k = names.index(outside[0])
            raise ParameterError(f"fit: fixed {outside[0]} = {held[outside[0]]:g} is outside the range of {law} "
                                 f"[{lower[k]:g}, {upper[k]:g}]")
        x0 = np.array(start)
        # the one factor of the moduli that fits best (the energy is linear in them)
        shape = np.concatenate(list(evaluate(np.clip(x0, lower, upper)).values()))
        if not np.isfinite(shape).all():
            raise ParameterError(f"fit: the start of {law} has no finite stress at the data; give another start")
        denominator = float((weights * shape) @ (weights * shape))
        scale = abs(float((weights * shape) @ (weights * target)) / denominator) if denominator > 0 else 1.0
        scale = scale if math.isfinite(scale) and scale > 0 else 1.0
        x0 = np.where(stress_like, x0 * scale, x0)
        for k, name in enumerate(names):
            x0[k] = start_values.get(name, x0[k])
        scaled = np.where(stress_like & free, scale, 1.0)
        lower, upper = lower * scaled, upper * scaled
        typical = np.maximum(np.where(stress_like, 1e-3 * scale, 1e-3), 1e-3 * np.abs(x0))
        expand = full(x0)
        if free.any():
            def reduced_residual(y: np.ndarray, expand: Callable[[np.ndarray], np.ndarray] = expand) -> np.ndarray:
                return residual(expand(y))

            reduced = _least_squares(reduced_residual, x0[free], lower[free], upper[free],
                                     typical[free], max_iterations)
            solution = _Solution(expand(reduced.x), reduced.cost, reduced.iterations, reduced.converged)
        else:  # everything held: the given law evaluated
            r = residual(x0)
            solution = _Solution(x0, 0.5 * float(r @ r), 0, True)
        if best is None or solution.cost < best.cost:
            best = solution
    assert best is not None

    values = {name: float(v) for name, v in zip(names, best.x, strict=True)}
    model_stress = evaluate(best.x)
    errors = {mode: _mode_error(curve, model_stress[mode]) for mode, curve in curves.items()}
    response.set_parameters([*best.x, K_fixed] if K_fixed is not None else best.x)
    lost, curves_fit = _stability_and_curves(response, curves)

    params_only = {k: v for k, v in values.items() if k != "K"}
    try:
        if fit_K:
            K = values["K"]
        elif K_fixed is not None:
            K = float(K_fixed)
        else:
            unit = model.material(params_only, 1.0, volumetric)  # K = 1 only to read the shear modulus
            K = BULK_RATIO * float(unit.mu if isinstance(unit, LameParameters) else
                                   max(unit.shear_moduli) if law == "fung_orthotropic" else unit.shear_modulus)
        material = model.material(params_only, K, volumetric)
    except ParameterError as exc:
        also = f" (fixed: {', '.join(f'{k} = {v:g}' for k, v in held.items())})" if held else ""
        raise ParameterError(f"fit: the fitted {law}{also} is refused by its parameter class: {exc}") from None
    return FitResult(
        law=law,
        terms=n_terms if law in _TERMS else None,
        parameters=values,
        material=material,
        incompressible=incompressible,
        bulk_modulus=K,
        volumetric=volumetric,
        weighting=weighting,
        data=curves,
        model=model_stress,
        errors=errors,
        stability_lost=lost,
        curves=curves_fit,
        iterations=best.iterations,
        converged=best.converged,
        fixed=tuple(n for n in names if n in held),
    )


def _held(law: str, names: Sequence[str], fixed: Mapping[str, float] | None) -> dict[str, float]:
    """``fit(fixed=...)`` checked: known names, finite numbers, a law's required ones given."""
    if fixed is not None and not isinstance(fixed, Mapping):
        raise ParameterError(f"fit: fixed must map parameter names to values, got {type(fixed).__name__}")
    held: dict[str, float] = {}
    for name, value in (fixed or {}).items():
        if name not in names:
            raise ParameterError(f"fit: {law} has no parameter {name!r}{_did_you_mean(str(name), names)} to fix; "
                                 f"parameters: {', '.join(names)}")
        if not is_finite_number(value):
            raise ParameterError(f"fit: fixed {name} must be a finite number, got {value!r}")
        held[name] = float(value)
    missing = [n for n in _REQUIRED_FIXED.get(law, ()) if n not in held]
    if missing:
        raise ParameterError(f"fit: {law} needs {', '.join(missing)} given in fixed (e.g. --fix "
                             f"{missing[0]}=1.0): no test along the material axes strains them (E12, E23, E31 = 0)")
    return held


# -- the plot --------------------------------------------------------------------------------------------
def plot_fits(results: Sequence[FitResult], path: str | Path, *, stress_unit: str = "MPa",
              title: str | None = None) -> Path:
    """A PNG of the data (markers) and each fit (lines), one panel per mode (matplotlib, Agg backend).

    Args:
        results: Fits of the same data (the data are drawn from the first).
        path: The PNG to write.
        stress_unit: Unit of the stress axis.
        title: Figure title (default: the laws).

    Raises:
        OutputError: matplotlib missing, or the file cannot be written.
    """
    if not results:
        raise ParameterError("plot_fits: no fit to plot")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise OutputError("plot_fits: needs matplotlib (pip install 'hyperfem[plot]')") from None
    modes = list(dict.fromkeys(k for r in results for k in r.data))  # the curves' labels
    fig, axes = plt.subplots(1, len(modes), figsize=(4.6 * len(modes), 4.2), squeeze=False)
    for ax, mode in zip(axes[0], modes, strict=True):
        data = next(r.data[mode] for r in results if mode in r.data)
        ax.plot(data.stretch, data.stress, "ko", markersize=4, label="data")
        for r in results:
            if mode in r.curves:
                lam, P = r.curves[mode]
                ax.plot(lam, P, "-", linewidth=1.4, label=f"{r.label}: rms {r.errors[mode].rms:.3g} {stress_unit}")
        ax.set_title(mode.replace("_", " ").replace("@", " at ") + ("°" if "@" in mode else ""))
        ax.set_xlabel("stretch λ [-]")
        ax.set_ylabel(f"nominal stress P₁₁ [{stress_unit}]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(title or ", ".join(r.label for r in results), fontsize=10)
    fig.tight_layout()
    path = Path(path)
    try:
        fig.savefig(path, dpi=120)
    except OSError as exc:
        raise OutputError(f"plot_fits: cannot write {path}: {exc}") from None
    finally:
        plt.close(fig)
    return path
