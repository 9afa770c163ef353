r"""Validated elastic parameter sets.

:class:`LameParameters` stores the Lamé pair :math:`(\mu, \lambda)` and can be
built from Young's modulus and Poisson's ratio:

.. math::
    \mu = \frac{E}{2(1+\nu)},\qquad \lambda = \frac{E\nu}{(1+\nu)(1-2\nu)}.
"""

from __future__ import annotations

from dataclasses import dataclass

from hyperfem.errors import ParameterError

from hyperfem.validation import check_positive, is_finite_number

__all__ = ["LameParameters"]


@dataclass(frozen=True)
class LameParameters:
    r"""Isotropic elastic constants :math:`(\mu, \lambda)` in consistent units (e.g. Pa).

    Attributes:
        mu: Shear modulus :math:`\mu > 0`.
        lmbda: First Lamé parameter; must give a positive bulk modulus
            :math:`\kappa = \lambda + 2\mu/3 > 0`.
    """

    mu: float
    lmbda: float

    def __post_init__(self) -> None:
        check_positive("mu", self.mu, "LameParameters")
        if not is_finite_number(self.lmbda):
            raise ParameterError(f"LameParameters: lmbda must be a finite number, got {self.lmbda!r}")
        if self.lmbda + 2.0 * self.mu / 3.0 <= 0:
            raise ParameterError(
                "LameParameters: bulk modulus lmbda + 2 mu/3 must be > 0, "
                f"got mu={self.mu!r}, lmbda={self.lmbda!r}"
            )

    @classmethod
    def from_youngs(cls, E: float, nu: float) -> LameParameters:
        """Build from Young's modulus ``E > 0`` and Poisson's ratio ``-1 < nu < 1/2``.

        Raises:
            ParameterError: If ``E <= 0`` or ``nu`` is outside the open interval (-1, 1/2).
        """
        check_positive("E", E, "LameParameters.from_youngs")
        if not (is_finite_number(nu) and -1.0 < nu < 0.5):
            raise ParameterError(
                f"LameParameters.from_youngs: Poisson ratio nu must lie in (-1, 0.5), got {nu!r}"
            )
        mu = E / (2.0 * (1.0 + nu))
        lmbda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
        return cls(mu=mu, lmbda=lmbda)

    @property
    def bulk_modulus(self) -> float:
        r"""Bulk modulus :math:`\kappa = \lambda + 2\mu/3`."""
        return self.lmbda + 2.0 * self.mu / 3.0

    @property
    def youngs_modulus(self) -> float:
        r"""Young's modulus :math:`E = \mu(3\lambda + 2\mu)/(\lambda + \mu)`."""
        return self.mu * (3.0 * self.lmbda + 2.0 * self.mu) / (self.lmbda + self.mu)

    @property
    def poisson_ratio(self) -> float:
        r"""Poisson's ratio :math:`\nu = \lambda / (2(\lambda + \mu))`."""
        return self.lmbda / (2.0 * (self.lmbda + self.mu))
