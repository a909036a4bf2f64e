"""Folders the tests read: the checkout, the tests' own data, the examples and the shared reference data."""

from __future__ import annotations

import os
from pathlib import Path

#: The checkout's root folder.
ROOT = Path(__file__).resolve().parent.parent
#: Small test inputs kept with the tests.
DATA = ROOT / "tests" / "data"
#: Example configurations and scripts.
EXAMPLES = ROOT / "examples"
#: The reference data folder (``../shared`` beside the checkout, or ``$PAMKIN_SHARED``).
SHARED = Path(os.environ.get("PAMKIN_SHARED", ROOT.parent / "shared"))
