"""Reading YAML: PyYAML's safe loader on libyaml's C parser where the installed PyYAML has it.

The model data file (``robot/data/gait2392.yaml``) takes ~0.22 s to parse with the pure-Python parser
and ~0.06 s with libyaml; a run reads it several times (skeleton, robot, audit). Same safe
subset and constructors either way (only the scanner/parser differ); errors are :class:`yaml.YAMLError`.
"""

from __future__ import annotations

import yaml

__all__ = ["safe_load"]

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def safe_load(text: str | bytes):
    """The Python object of a YAML document (safe tags only), as :func:`yaml.safe_load`."""
    return yaml.load(text, Loader=_LOADER)  # noqa: S506 - a safe loader
