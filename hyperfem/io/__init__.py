"""Input/output: point probes, quadrature-point minima, VTX files, JSON summaries, collective output-folder checks."""

from hyperfem.io.probes import PointProbe, QuadratureMinimum
from hyperfem.io.results import VTXOutput, ensure_output_dir, on_rank0, write_json

__all__ = ["PointProbe", "QuadratureMinimum", "VTXOutput", "ensure_output_dir", "on_rank0", "write_json"]
