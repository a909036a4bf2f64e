"""Reading YAML: PyYAML's safe loader on libyaml's C parser where the installed PyYAML has it.

The model data file (``robot/data/gait2392.yaml``) takes ~0.22 s to parse with the pure-Python parser
and ~0.06 s with libyaml; a run reads it several times (skeleton, robot, audit). Same safe
subset and constructors either way (only the scanner/parser differ); errors are :class:`yaml.YAMLError`.
"""

from __future__ import annotations

import yaml

from pamkin.errors import DataFileError

__all__ = ["MAX_USER_YAML_BYTES", "safe_load", "strict_load"]

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def safe_load(text: str | bytes):
    """The Python object of a YAML document (safe tags only), as :func:`yaml.safe_load`."""
    return yaml.load(text, Loader=_LOADER)  # noqa: S506 - a safe loader


class _StrictLoader(yaml.SafeLoader):
    """The safe loader, refusing duplicate keys and anchors/aliases (a user file needs neither, and aliases
    expand without bound: a 34 kB 'billion laughs' file takes gigabytes)."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.constructor.ConstructorError(None, None, "anchors and aliases (&, *) are not allowed",
                                                    event.start_mark)
        event = self.peek_event()
        if getattr(event, "anchor", None):
            raise yaml.constructor.ConstructorError(None, None, "anchors and aliases (&, *) are not allowed",
                                                    event.start_mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):
        seen: set = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if isinstance(key, (list, dict)):
                raise yaml.constructor.ConstructorError(None, None, "a mapping key must be a scalar",
                                                        key_node.start_mark)
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep)


#: The largest user YAML file read [bytes] (the built-in designs are about 40 kB).
MAX_USER_YAML_BYTES = 5_000_000


def strict_load(raw: bytes | str, path: str = "<yaml>"):
    """A user's YAML file (a design, a limits file): UTF-8 text, no duplicate keys, no anchors or aliases,
    at most :data:`MAX_USER_YAML_BYTES`.

    Raises:
        pamkin.errors.DataFileError: naming the file and, for a YAML problem, the line.
    """
    if isinstance(raw, str):
        raw = raw.encode("utf-8")
    if len(raw) > MAX_USER_YAML_BYTES:
        raise DataFileError(path, f"{len(raw)} bytes: larger than the {MAX_USER_YAML_BYTES} a design or limits "
                                  "file may have")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise DataFileError(path, f"not UTF-8 text (byte {e.start}): save it as UTF-8") from None
    if text.startswith("\ufeff"):
        text = text[1:]
    try:
        return yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a safe loader
    except yaml.YAMLError as e:
        raise DataFileError(path, f"not valid YAML: {' '.join(str(e).split())}") from None
