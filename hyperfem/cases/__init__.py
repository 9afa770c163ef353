"""Reference set-ups from the seed documents, shared by demos, tests and benchmarks."""

from hyperfem.cases.cantilever import (
    BEND_TRACTION,
    TEST_POINT,
    TWIST_MAGNITUDE,
    CantileverSpec,
    bend_load,
    twist_load,
)

__all__ = ["BEND_TRACTION", "TEST_POINT", "TWIST_MAGNITUDE", "CantileverSpec", "bend_load", "twist_load"]
