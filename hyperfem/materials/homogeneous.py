r"""Homogeneous test modes and the nominal stress a strain energy gives under them.

The four modes of a material test, :math:`\lambda` the stretch along :math:`e_1` and
:math:`a` the lateral stretch, the reported stress the nominal (first Piola–Kirchhoff)
:math:`P_{11}`, force per undeformed area:

* ``uniaxial``: :math:`F = \operatorname{diag}(\lambda, a, a)`, :math:`P_{22} = P_{33} = 0`;
  incompressible :math:`a = \lambda^{-1/2}`;
* ``equibiaxial``: :math:`F = \operatorname{diag}(\lambda, \lambda, a)`, :math:`P_{33} = 0`
  (:math:`P_{22} = P_{11}`); incompressible :math:`a = \lambda^{-2}`;
* ``pure_shear`` (planar tension, the width held): :math:`F = \operatorname{diag}(\lambda, 1, a)`,
  :math:`P_{33} = 0`; incompressible :math:`a = \lambda^{-1}`;
* ``volumetric`` (compressible only): :math:`F = \lambda I`, :math:`J = \lambda^3`,
  :math:`P_{11} = P_{22} = P_{33}` (a pressure :math:`p` measured against :math:`J` is
  :math:`P_{11} = -p\,J^{2/3}`).

**The stress comes from the energy itself**, never from a second formula:
:math:`\psi(F)` is written once in UFL with :math:`F` a DG0 :math:`3\times3` field
on an interval mesh (``MPI.COMM_SELF``), one cell per state, and the material
parameters :class:`dolfinx.fem.Constant`\ s; the diagonal of :math:`P = \partial\psi/\partial F`
(``ufl.diff``) is compiled once into a :class:`dolfinx.fem.Expression`. Changing
the parameters or the stretches then only sets numbers: a fit evaluates the same
kernel thousands of times and nothing recompiles. (One state per cell of one
mesh evaluates 60 states in 0.08 ms; the same 60 states as a one-cell mesh with
a ``Constant`` :math:`F` take 2.4 ms, one call each.)

*Incompressible* (the energy is the law's isochoric part :math:`\bar\psi`): with
:math:`\det F = 1`, :math:`P = \partial\bar\psi/\partial F - pF^{-T}` and the
pressure follows from the free face, :math:`p = \lambda_3 S_{33}` with
:math:`S = \partial\bar\psi/\partial F`, so :math:`P_{11} = S_{11} - p/\lambda`.

*Compressible* (the full energy): the lateral stretch solves :math:`P_{ff}(a) = 0`
on the free face by Newton's method, all states at once (the derivative by a
difference of the same kernel).

**Drucker stability** (the check of the Abaqus Theory Manual, §4.6.1):
:math:`d\tau : d\varepsilon > 0` for every increment :math:`d\varepsilon` of the
logarithmic principal strains. For an isotropic energy
:math:`W(\varepsilon) = \psi(\operatorname{diag} e^{\varepsilon_i})` the principal
Kirchhoff stresses are :math:`\tau_i = \partial W/\partial\varepsilon_i = \lambda_iP_{ii}`,
so the condition is the positive definiteness of the Hessian
:math:`H_{ij} = \partial\tau_i/\partial\varepsilon_j` — on the plane
:math:`\sum_i d\varepsilon_i = 0` for an incompressible law (the pressure does no
work there), on all of :math:`\mathbb R^3` for a compressible one.
:meth:`HomogeneousResponse.drucker` returns its smallest eigenvalue (stress units;
:math:`2\mu_0` at :math:`F = I`), :math:`H` from central differences of the
compiled :math:`\tau` (step :math:`10^{-4}`: relative error :math:`\sim10^{-8}`,
and no second kernel to compile — Ogden's tangent takes 16 s).

**Fibres** (``fibres=True``): the energy also gets ``constants["fibre_angle"]``, a DG0
field holding each state's angle :math:`\theta` (radians) of the fibres to
:math:`e_1` in the :math:`e_1`–:math:`e_2` plane (the fitting laws build their
directions from it, e.g. HGO's two families :math:`(\cos\theta, \pm\sin\theta, 0)`).
Every method takes ``angle`` (one per state, or one for all). With the material
symmetric about the test axes the principal stretches stay those of the test,
but the two lateral stretches of an incompressible uniaxial test differ: the
free faces give :math:`\tau_{22} = \tau_{33}` (:math:`\tau_i = \lambda_iP_{ii}` without the
pressure), solved for :math:`\lambda_2` with :math:`\lambda_3 = 1/(\lambda\lambda_2)` by Newton's method on
:math:`\ln\lambda_2`, all states at once. Equibiaxial and pure shear prescribe both
in-plane stretches and report :math:`P_{11}` (the :math:`P_{22}` of an equibiaxial test is the
:math:`P_{11}` of the angle :math:`90^\circ - \theta`). Drucker's check then covers the increments of
the stretches along the test axes (not shears).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import ufl
from mpi4py import MPI

from dolfinx import fem
from dolfinx import mesh as dmesh

from hyperfem.errors import ParameterError

__all__ = [
    "DRUCKER_STEP",
    "INCOMPRESSIBLE_MODES",
    "MODES",
    "HomogeneousResponse",
    "Mode",
    "check_mode",
    "mode_stretches",
]

Expr = ufl.core.expr.Expr
Energy = Callable[[Expr, Mapping[str, Expr]], Expr]
"""``energy(F, constants)``: the strain energy of the deformation gradient with the parameters as UFL constants."""

DRUCKER_STEP = 1e-4
r"""Step in the logarithmic strains of the central differences of :meth:`HomogeneousResponse.drucker`."""


@dataclass(frozen=True)
class Mode:
    r"""A homogeneous test: its principal stretches of the stretch :math:`\lambda` and a lateral one :math:`a`.

    Attributes:
        name: ``uniaxial``, ``equibiaxial``, ``pure_shear`` or ``volumetric``.
        pattern: Each principal stretch: ``"s"`` the test stretch :math:`\lambda`, ``"a"`` the lateral
            stretch, ``"1"`` held at 1.
        free: Index of the traction-free principal direction (``None``: no free face).
        incompressible_exponent: :math:`a = \lambda^{k}` at :math:`\det F = 1` (``None``: no such state).
    """

    name: str
    pattern: tuple[str, str, str]
    free: int | None
    incompressible_exponent: float | None

    def stretches(self, stretch: np.ndarray, lateral: np.ndarray) -> np.ndarray:
        """The principal stretches, shape ``(n, 3)``, of test stretches ``stretch`` and lateral ones ``lateral``."""
        columns = {"s": stretch, "a": lateral, "1": np.ones_like(stretch)}
        return np.stack([columns[p] for p in self.pattern], axis=1)

    def incompressible_lateral(self, stretch: np.ndarray) -> np.ndarray:
        r"""The lateral stretch at :math:`\det F = 1`."""
        if self.incompressible_exponent is None:
            raise ParameterError(f"{self.name}: an incompressible material has no {self.name} deformation")
        return stretch**self.incompressible_exponent


_MODE_LIST = (
    Mode("uniaxial", ("s", "a", "a"), 2, -0.5),
    Mode("equibiaxial", ("s", "s", "a"), 2, -2.0),
    Mode("pure_shear", ("s", "1", "a"), 2, -1.0),
    Mode("volumetric", ("s", "s", "s"), None, None),
)
MODES: dict[str, Mode] = {m.name: m for m in _MODE_LIST}
"""The homogeneous modes by name (module docstring)."""

INCOMPRESSIBLE_MODES: tuple[str, ...] = ("uniaxial", "equibiaxial", "pure_shear")
"""The modes an incompressible material can undergo."""


def check_mode(name: object) -> Mode:
    """The mode called ``name``; :class:`ParameterError` with the available names otherwise."""
    if not isinstance(name, str) or name not in MODES:
        raise ParameterError(f"unknown test mode {name!r} (modes: {', '.join(MODES)})")
    return MODES[name]


def mode_stretches(mode: str, stretch: Sequence[float] | np.ndarray) -> np.ndarray:
    """The principal stretches ``(n, 3)`` of an incompressible ``mode`` at the test stretches ``stretch``."""
    m = check_mode(mode)
    lam = np.asarray(stretch, dtype=float)
    return m.stretches(lam, m.incompressible_lateral(lam))


class HomogeneousResponse:
    r"""The principal nominal stresses of a strain energy at diagonal :math:`F`, compiled once.

    Args:
        energy: ``energy(F, constants) -> psi``: for an incompressible response the law's
            isochoric part, else the full energy; ``constants`` maps each name of
            ``parameters`` to a :class:`dolfinx.fem.Constant`.
        parameters: Names of the parameters, in the order :meth:`set_parameters` takes them.
        incompressible: Eliminate the pressure (module docstring) instead of solving for
            the lateral stretch.
        capacity: States per kernel call (longer batches are evaluated in chunks).

    Example::

        response = HomogeneousResponse(lambda F, c: neo_hookean_isochoric(F, c["mu"]), ["mu"], incompressible=True)
        response.set_parameters([0.4])
        P = response.nominal_stress("uniaxial", [1.0, 2.0, 3.0])  # 0.4 (lambda - lambda^-2)
    """

    def __init__(
        self, energy: Energy, parameters: Sequence[str], *, incompressible: bool, capacity: int = 256,
        fibres: bool = False,
    ) -> None:
        self.parameters = tuple(parameters)
        self.incompressible = bool(incompressible)
        self.fibres = bool(fibres)
        self.capacity = int(capacity)
        self._mesh = dmesh.create_interval(MPI.COMM_SELF, self.capacity, [0.0, 1.0])
        self._F = fem.Function(fem.functionspace(self._mesh, ("DG", 0, (3, 3))))
        self._constants: dict[str, Any] = {name: fem.Constant(self._mesh, 0.0) for name in self.parameters}
        given: dict[str, Any] = dict(self._constants)
        if self.fibres:
            self._angle = fem.Function(fem.functionspace(self._mesh, ("DG", 0)))
            given["fibre_angle"] = self._angle
        F = ufl.variable(self._F)
        P = ufl.diff(energy(F, given), F)
        self._expression = fem.Expression(ufl.as_vector([P[0, 0], P[1, 1], P[2, 2]]), np.array([[0.5]]))
        self._cells = np.arange(self.capacity, dtype=np.int32)
        self._values = np.zeros((self.capacity, 3, 3))

    # -- parameters and raw kernel ---------------------------------------------------------------
    def set_parameters(self, values: Sequence[float] | np.ndarray | Mapping[str, float]) -> None:
        """Set the parameter constants (a sequence in the order of :attr:`parameters`, or a mapping)."""
        if isinstance(values, Mapping):
            missing = [n for n in self.parameters if n not in values]
            if missing:
                raise ParameterError(f"HomogeneousResponse: no value for {', '.join(missing)}")
            values = [values[n] for n in self.parameters]
        if len(values) != len(self.parameters):
            raise ParameterError(
                f"HomogeneousResponse: {len(self.parameters)} parameters ({', '.join(self.parameters)}), "
                f"got {len(values)} values"
            )
        for name, value in zip(self.parameters, values, strict=True):
            self._constants[name].value = float(value)

    def _angles(self, angle: float | Sequence[float] | np.ndarray | None, n: int) -> np.ndarray:
        """The fibre angle of each of ``n`` states (a shorter array repeats: blocks of states)."""
        if not self.fibres:
            if angle is not None:
                raise ParameterError("HomogeneousResponse: a fibre angle for a response without fibres")
            return np.zeros(0)
        if angle is None:
            raise ParameterError("HomogeneousResponse: a response with fibres needs the fibre angle of each state")
        return np.resize(np.asarray(angle, dtype=float).reshape(-1), n)

    def principal_stress(self, stretches: np.ndarray, angle: float | np.ndarray | None = None) -> np.ndarray:
        r""":math:`(P_{11}, P_{22}, P_{33})` of :math:`\partial\psi/\partial F` at :math:`F = \operatorname{diag}`
        of each row of ``stretches`` (shape ``(n, 3)``), no pressure added; ``angle``: the fibre angles."""
        stretches = np.asarray(stretches, dtype=float).reshape(-1, 3)
        angles = self._angles(angle, len(stretches))
        out = np.empty_like(stretches)
        for start in range(0, len(stretches), self.capacity):
            chunk = stretches[start : start + self.capacity]
            n = len(chunk)
            self._values[:n] = 0.0
            for i in range(3):
                self._values[:n, i, i] = chunk[:, i]
            self._F.x.array[: 9 * n] = self._values[:n].reshape(-1)
            if self.fibres:
                self._angle.x.array[:n] = angles[start : start + n]
            out[start : start + n] = self._expression.eval(self._mesh, self._cells[:n]).reshape(n, 3)
        return out

    # -- the modes ----------------------------------------------------------------------------------
    def states(self, mode: str, stretch: Sequence[float] | np.ndarray,
               angle: float | np.ndarray | None = None) -> np.ndarray:
        r"""The principal stretches ``(n, 3)`` of ``mode``: incompressible, or with the lateral stretch solved."""
        m = check_mode(mode)
        lam = np.asarray(stretch, dtype=float).reshape(-1)
        if self.incompressible:
            if self.fibres and m.name == "uniaxial":
                return self._fibre_uniaxial(lam, self._angles(angle, len(lam)))
            return m.stretches(lam, m.incompressible_lateral(lam))
        if self.fibres:
            raise ParameterError("HomogeneousResponse: fibres are incompressible only")
        if m.free is None:
            return m.stretches(lam, lam)
        return m.stretches(lam, self._lateral(m, lam))

    def _fibre_uniaxial(self, lam: np.ndarray, angles: np.ndarray, iterations: int = 60) -> np.ndarray:
        r"""Incompressible uniaxial states with :math:`\tau_{22} = \tau_{33}` (module docstring); NaN rows where
        Newton's method on :math:`\ln\lambda_2` does not converge."""
        n = len(lam)
        x = -0.5 * np.log(lam)  # ln lambda_2: the isotropic state
        h = 1e-7

        def states(x: np.ndarray) -> np.ndarray:
            return np.stack([lam, np.exp(x), 1.0 / (lam * np.exp(x))], axis=1)

        done = np.zeros(n, dtype=bool)
        for _ in range(iterations):
            both = np.concatenate([states(x), states(x + h)])
            tau = both * self.principal_stress(both, np.concatenate([angles, angles]))
            g, g_h = tau[:n, 1] - tau[:n, 2], tau[n:, 1] - tau[n:, 2]
            slope = (g_h - g) / h
            step = np.clip(-g / np.where(slope > 0.0, slope, np.nan), -0.5, 0.5)  # NaN where the slope is lost
            x = x + step
            done = np.abs(step) <= 1e-11
            if done.all():
                return states(x)
            if not np.isfinite(x).any():
                break
        return np.where(done[:, None], states(x), np.nan)

    def nominal_stress(self, mode: str, stretch: Sequence[float] | np.ndarray,
                       angle: float | np.ndarray | None = None) -> np.ndarray:
        r"""The nominal stress :math:`P_{11}` of ``mode`` at each test stretch (module docstring)."""
        m = check_mode(mode)
        states = self.states(mode, stretch, angle)
        P = self.principal_stress(states, None if angle is None else self._angles(angle, len(states)))
        if self.incompressible:
            assert m.free is not None  # an incompressible mode has a free face
            pressure = P[:, m.free] * states[:, m.free]
            return P[:, 0] - pressure / states[:, 0]
        return P[:, 0]

    def _lateral(self, mode: Mode, lam: np.ndarray, iterations: int = 60) -> np.ndarray:
        r"""Newton's method for :math:`P_{ff}(a) = 0`, all states at once; NaN where it does not converge."""
        assert mode.free is not None and mode.incompressible_exponent is not None
        f = mode.free
        a = lam**mode.incompressible_exponent  # the incompressible state: a start on the right side for large K
        h = 1e-7
        done = np.zeros(len(lam), dtype=bool)  # (NaN compares False: never done)
        for _ in range(iterations):
            both = np.concatenate([mode.stretches(lam, a), mode.stretches(lam, a * (1.0 + h))])
            P = self.principal_stress(both)
            g, g_h = P[: len(lam), f], P[len(lam) :, f]
            slope = (g_h - g) / (a * h)
            step = -g / np.where(slope > 0.0, slope, np.nan)  # NaN where the slope is lost
            a = np.clip(a + step, 0.5 * a, 2.0 * a)
            # converged: this (last) Newton step moved a by less than 1e-10 of itself
            done = np.abs(step) <= 1e-10 * a
            if done.all():
                return a
            if not np.isfinite(a).any():
                break
        return np.where(done, a, np.nan)

    def drucker(self, mode: str, stretch: Sequence[float] | np.ndarray,
                angle: float | np.ndarray | None = None) -> np.ndarray:
        r"""The smallest eigenvalue of :math:`\partial\tau_i/\partial\varepsilon_j` along ``mode`` (module docstring).

        Positive where the law is Drucker stable; on the plane :math:`\sum_i d\varepsilon_i = 0` for an
        incompressible response. NaN where the state has no finite stress.
        """
        states = self.states(mode, stretch, angle)
        n = len(states)
        angles = None if angle is None else self._angles(angle, n)
        if self.incompressible:  # an orthonormal basis of the plane sum = 0
            basis = np.array([[1.0, -1.0, 0.0], [1.0, 1.0, -2.0]]).T / np.sqrt([2.0, 6.0])
        else:
            basis = np.eye(3)
        k = basis.shape[1]
        log = np.log(states)
        shifted = [log + sign * DRUCKER_STEP * basis[:, j] for j in range(k) for sign in (1.0, -1.0)]
        stretches = np.exp(np.concatenate(shifted))
        tau = (stretches * self.principal_stress(stretches, angles)).reshape(2 * k, n, 3)
        columns = [(tau[2 * j] - tau[2 * j + 1]) / (2.0 * DRUCKER_STEP) for j in range(k)]  # H v_j, (n, 3) each
        H = np.einsum("ia,nib->nab", basis, np.stack(columns, axis=2))  # V^T H V
        H = 0.5 * (H + np.transpose(H, (0, 2, 1)))
        smallest = np.full(n, np.nan)
        finite = np.isfinite(H).all(axis=(1, 2))
        if finite.any():
            smallest[finite] = np.linalg.eigvalsh(H[finite])[:, 0]
        return smallest
