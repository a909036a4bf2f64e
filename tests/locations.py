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


def load_model(path):
    """``pamkin.load_osim(path)`` with the skipped-components warning silenced (models with markers, contact...)."""
    import warnings  # noqa: PLC0415

    import pamkin  # noqa: PLC0415  (not at import: conftest sets the cache folders first)
    from pamkin.opensim.model_file import SkippedComponentsWarning  # noqa: PLC0415

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SkippedComponentsWarning)
        return pamkin.load_osim(path)
