"""Input/output: point probes, VTX files, JSON summaries."""

from hyperfem.io.probes import PointProbe
from hyperfem.io.results import VTXOutput, write_json

__all__ = ["PointProbe", "VTXOutput", "write_json"]
