"""Shared fixtures: the Gait2392 model and OpenSim reference numbers (child process)."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

# Tests write nothing outside the checkout and temporary folders: the URDF cache of imported models
# (pamkin.load_osim) and matplotlib's cache go to a temporary folder unless set explicitly (CI sets
# PAMKIN_CACHE inside its virtual environment). Set here, before pamkin or matplotlib is imported.
_TMP_CACHE = None
if "PAMKIN_CACHE" not in os.environ or "MPLCONFIGDIR" not in os.environ:
    _TMP_CACHE = tempfile.mkdtemp(prefix="pamkin-test-cache-")
    os.environ.setdefault("PAMKIN_CACHE", os.path.join(_TMP_CACHE, "pamkin"))
    os.environ.setdefault("MPLCONFIGDIR", os.path.join(_TMP_CACHE, "matplotlib"))

from opensim_ref import GAIT2392, GAIT2392_MILLARD, SHARED  # noqa: E402


def pytest_unconfigure(config):
    if _TMP_CACHE is not None:
        shutil.rmtree(_TMP_CACHE, ignore_errors=True)


def pytest_collection_modifyitems(config, items):
    if not GAIT2392.exists():
        skip = pytest.mark.skip(reason=f"reference data not found at {SHARED}")
        for item in items:
            if "opensim" in item.keywords or "needs_shared" in item.keywords:
                item.add_marker(skip)


@pytest.fixture(scope="session")
def gait2392_path() -> Path:
    if not GAIT2392.exists():
        pytest.skip(f"Gait2392 not found at {GAIT2392}")
    return GAIT2392


@pytest.fixture(scope="session")
def millard_path() -> Path:
    if not GAIT2392_MILLARD.exists():
        pytest.skip("Gait2392 Millard model not found")
    return GAIT2392_MILLARD


@pytest.fixture(scope="session")
def gait2392(gait2392_path):
    import pamkin

    return pamkin.load_osim(gait2392_path)
