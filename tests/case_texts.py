"""Case-file texts shared by the case-file tests (``test_casefile.py``, ``test_cli_errors.py``).

Imported as a plain module: pytest puts ``tests/`` (no ``__init__.py``) on
``sys.path`` when it collects a test module there (its default ``prepend``
import mode), serially and under ``mpiexec``.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["BASE", "MESH", "ROOT"]

ROOT = Path(__file__).resolve().parent.parent
MESH = ROOT / "meshes" / "beam_h2.msh"

BASE = f"""[mesh]
file = "{MESH}"

[[material]]
law = "neo_hookean"
E = 1.0e6
nu = 0.3

[[bc]]
type = "clamp"
boundary = "clamped"

[[load]]
type = "dead_traction"
boundary = "free_end"
value = [0.0, -5.0e3, 0.0]
"""
"""The bend case on beam_h2 (P2 by default): neo-Hookean, clamped at x = -5, a dead traction on the free end.

Line numbers matter: ``law`` is on line 5 (the syntax-error test of ``test_cli_errors.py``).
"""
