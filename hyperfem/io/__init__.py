"""Input/output: point probes, VTX/XDMF files, JSON summaries, checkpoints.

Output folders are checked collectively (every rank raises the same error).
"""

from hyperfem.io.checkpoint import CheckpointError, read_functions, read_meta, resolve_checkpoint, write_checkpoint
from hyperfem.io.probes import PointProbe
from hyperfem.io.results import VTXWriter, XDMFWriter, ensure_output_dir, on_rank0, vtx_steps, write_json

__all__ = [
    "CheckpointError",
    "PointProbe",
    "VTXWriter",
    "XDMFWriter",
    "ensure_output_dir",
    "on_rank0",
    "read_functions",
    "read_meta",
    "resolve_checkpoint",
    "vtx_steps",
    "write_checkpoint",
    "write_json",
]
