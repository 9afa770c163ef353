"""Hertz under refinement (issue 19): a rigid sphere (R = 0.5) pressed 0.02 into a quarter block.

The indentation of ``demos/contact.py`` on meshes of 8, 12 and 16 cells per
side. The contact radius measured from the second moment of the nodal
contact forces converges to Hertz's :math:`a = (3FR/4E^*)^{1/3}`: measured
0.915, 0.944, 0.956 of it (errors falling about as :math:`h`), and the
first-order Richardson extrapolation of the two finer meshes gives 0.994.
The force at a given depth falls too (1.24, 1.18, 1.16 × Hertz), toward a
limit about 8 % above Hertz: the block's clamped bottom 10 contact radii
below removes the half-space's far-field compliance (the demo says how
much). Every state stays at a positive distance from the sphere.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

pytest.importorskip("ipctk")  # the demo imports the contact package, which needs it for mesh contact only

# A convergence study on three meshes (16 s of the suite's budget per pass); 1 rank = 2 ranks of contact is
# checked by tests/test_contact.py and the demos' tests, so this runs serially only.
pytestmark = pytest.mark.serial

DEMO = Path(__file__).resolve().parent.parent / "demos" / "contact.py"
SIZES = (8, 12, 16)


@pytest.fixture(scope="module")
def indentations():
    from mpi4py import MPI

    spec = importlib.util.spec_from_file_location("demo_contact_hertz", DEMO)
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    return {n: demo.sphere_indentation(MPI.COMM_WORLD, n, 0.02) for n in SIZES}


def test_contact_radius_converges_to_hertz(indentations):
    ratios = [indentations[n]["contact_radius"] / indentations[n]["contact_radius_hertz"] for n in SIZES]
    errors = [abs(1.0 - r) for r in ratios]
    assert errors[0] > errors[1] > errors[2], ratios
    assert errors[2] < 0.06, ratios
    # First order in h (measured): the extrapolation of the two finer meshes.
    h1, h2 = 1.0 / SIZES[1], 1.0 / SIZES[2]
    extrapolated = (ratios[2] * h1 - ratios[1] * h2) / (h1 - h2)
    assert extrapolated == pytest.approx(1.0, abs=0.02), (ratios, extrapolated)


def test_force_falls_under_refinement_and_follows_the_power_three_halves(indentations):
    force_ratios = [indentations[n]["ratio_to_hertz"][-1] for n in SIZES]
    assert force_ratios[0] > force_ratios[1] > force_ratios[2] > 1.0, force_ratios
    assert force_ratios[2] < 1.2, force_ratios
    for n in SIZES:
        result = indentations[n]
        assert result["completed"] and result["min_distance"] > 0.0
        assert result["exponent"] == pytest.approx(1.5, abs=0.1)
