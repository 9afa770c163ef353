"""Input/output: point probes, VTX files, JSON summaries, collective output-folder checks."""

from hyperfem.io.probes import PointProbe
from hyperfem.io.results import VTXOutput, ensure_output_dir, on_rank0, write_json

__all__ = ["PointProbe", "VTXOutput", "ensure_output_dir", "on_rank0", "write_json"]
