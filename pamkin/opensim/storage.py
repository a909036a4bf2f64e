"""OpenSim storage files (``.mot`` / ``.sto``): header, units and named columns.

Format (OpenSim 4.x "Storage" text files, as written by IK, ID and the GRF tools)::

    <name>                       # first line: the table's name (any text)
    version=1
    nRows=211
    nColumns=24
    inDegrees=yes                # angles in degrees (yes) or radians (no)
    <free text lines>
    endheader
    time<TAB>col1<TAB>col2 ...   # column labels, the first is time [s]
    0.5<TAB>...                  # nRows rows of nColumns numbers (tab or space separated)

``nRows``/``nColumns`` are checked when present (``nColumns`` counts the time column);
``inDegrees`` is optional in the file (``in_degrees`` is then ``None``) and must be ``yes`` or
``no`` otherwise. Header lines may carry trailing tabs (as ``subject01_walk1_grf.mot`` does).
Every problem raises :class:`~pamkin.errors.StorageFileError` naming the file (and the column
or line).

Units: the reader converts nothing. :meth:`Storage.values` returns the numbers as stored;
:meth:`Storage.coordinates_si` converts rotational coordinates from degrees to radians when
the header says ``inDegrees=yes`` (translations stay in metres).
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pamkin.errors import StorageFileError

__all__ = ["Storage", "read_storage"]


@dataclass(frozen=True)
class Storage:
    """One OpenSim storage table.

    Attributes:
        path: The file read.
        name: Its first header line (the table name).
        header: ``key=value`` header entries (``version``, ``nRows``, ``nColumns``,
            ``inDegrees``, ...), values as text.
        in_degrees: ``True``/``False`` from ``inDegrees=yes|no``; ``None`` if absent.
        columns: Column labels after ``time``, file order.
        time: (N,) times [s], strictly increasing.
        data: (N, len(columns)) values as stored in the file.
        notes: Header lines that are not ``key=value`` entries (free text).
    """

    path: str
    name: str
    header: dict[str, str]
    in_degrees: bool | None
    columns: tuple[str, ...]
    time: np.ndarray
    data: np.ndarray
    notes: tuple[str, ...] = field(default=())

    def __len__(self) -> int:
        return len(self.time)

    def __contains__(self, column: object) -> bool:
        return column in self.columns

    def _index(self, column: str) -> int:
        try:
            return self.columns.index(column)
        except ValueError:
            close = difflib.get_close_matches(column, self.columns, n=3)
            hint = f"; did you mean {close}?" if close else ""
            raise StorageFileError(self.path, f"no such column (the file has {len(self.columns)}: "
                                              f"{', '.join(self.columns)}){hint}", column=column) from None

    def column(self, column: str) -> np.ndarray:
        """Values of one column as stored, (N,).

        Raises:
            StorageFileError: The file has no such column (names the file and the column).
        """
        return self.data[:, self._index(column)].copy()

    def values(self, columns: Sequence[str]) -> np.ndarray:
        """Values of several columns as stored, (N, len(columns)).

        Raises:
            StorageFileError: Naming the first missing column (and the file).
        """
        idx = [self._index(c) for c in columns]
        return self.data[:, idx].copy()

    def interpolate(self, times: Iterable[float] | np.ndarray, columns: Sequence[str],
                    tolerance: float = 1e-4) -> np.ndarray:
        """Columns linearly interpolated at ``times`` [s], (len(times), len(columns)), as stored.

        Args:
            times: Query times [s].
            columns: Column labels.
            tolerance: Times up to this far [s] outside the file's time range are taken as its
                first/last row (OpenSim writes times such as 1.59999886 for 1.6).

        Raises:
            StorageFileError: A missing column, or a time outside the file's range.
        """
        t = np.asarray(times, dtype=float).ravel()
        vals = self.values(columns)
        lo, hi = float(self.time[0]), float(self.time[-1])
        bad = (t < lo - tolerance) | (t > hi + tolerance)
        if bad.any():
            raise StorageFileError(self.path, f"{int(bad.sum())} requested time(s) outside the file's time range "
                                              f"[{lo:.6g}, {hi:.6g}] s (first {t[bad][0]:.6g} s)")
        out = np.empty((len(t), len(columns)))
        for j in range(len(columns)):
            out[:, j] = np.interp(t, self.time, vals[:, j])
        return out

    def coordinates_si(self, names: Sequence[str], rotational: Sequence[bool]) -> np.ndarray:
        """Coordinate columns in SI units (radians, metres), (N, len(names)).

        Rotational coordinates are converted from degrees when ``inDegrees=yes``; a file
        without an ``inDegrees`` entry is refused (its angle unit is unknown).

        Args:
            names: Coordinate (column) names.
            rotational: Per name, True for an angle, False for a translation.

        Raises:
            StorageFileError: A missing column, or no ``inDegrees`` in the header.
        """
        if self.in_degrees is None:
            raise StorageFileError(self.path, "the header has no inDegrees=yes|no entry: the angle unit is unknown")
        vals = self.values(names)
        if self.in_degrees:
            rot = np.asarray(rotational, dtype=bool)
            vals[:, rot] = np.radians(vals[:, rot])
        return vals


def _int_entry(path: str, header: dict[str, str], key: str) -> int | None:
    if key not in header:
        return None
    try:
        return int(header[key])
    except ValueError:
        raise StorageFileError(path, f"header entry {key}={header[key]!r} is not an integer") from None


def read_storage(path: str | os.PathLike) -> Storage:
    """Read an OpenSim ``.mot``/``.sto`` storage file.

    Raises:
        StorageFileError: Missing file, no ``endheader``, a bad ``inDegrees``/``nRows``/
            ``nColumns`` entry, a first column other than ``time``, duplicate or empty
            column labels, rows of the wrong length, non-numeric or non-finite values,
            times not strictly increasing, or row/column counts disagreeing with the header.
    """
    p = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        raise StorageFileError(p, "file not found") from None
    except OSError as e:
        raise StorageFileError(p, f"cannot read: {e}") from None
    lines = text.splitlines()
    try:
        end = next(i for i, line in enumerate(lines) if line.strip().lower() == "endheader")
    except StopIteration:
        raise StorageFileError(p, "no 'endheader' line: not an OpenSim storage file") from None
    head = [line.strip() for line in lines[:end]]
    name = head[0] if head else ""
    header: dict[str, str] = {}
    notes = []
    for line in head[1:] if head else []:
        if "=" in line and " " not in line.split("=", 1)[0]:
            k, v = line.split("=", 1)
            header[k.strip()] = v.strip()
        elif line:
            notes.append(line)
    in_deg: bool | None = None
    if "inDegrees" in header:
        v = header["inDegrees"].lower()
        if v not in ("yes", "no"):
            raise StorageFileError(p, f"header entry inDegrees={header['inDegrees']!r}: expected 'yes' or 'no'")
        in_deg = v == "yes"
    n_rows = _int_entry(p, header, "nRows")
    n_cols = _int_entry(p, header, "nColumns")

    body = [(end + 1 + i, line) for i, line in enumerate(lines[end + 1:]) if line.strip()]
    if not body:
        raise StorageFileError(p, "no column labels after 'endheader'")
    labels = body[0][1].strip().split("\t") if "\t" in body[0][1] else body[0][1].split()
    labels = [s.strip() for s in labels]
    while labels and labels[-1] == "":
        labels.pop()
    if not labels or labels[0].lower() != "time":
        raise StorageFileError(p, f"line {body[0][0] + 1}: the first column must be 'time', got "
                                  f"{labels[0] if labels else ''!r}")
    if any(s == "" for s in labels):
        raise StorageFileError(p, f"line {body[0][0] + 1}: empty column label (column {labels.index('') + 1})")
    dup = sorted({s for s in labels if labels.count(s) > 1})
    if dup:
        raise StorageFileError(p, f"duplicate column label(s) {dup}", column=dup[0])
    ncol = len(labels)
    if n_cols is not None and n_cols != ncol:
        raise StorageFileError(p, f"header says nColumns={n_cols} but the table has {ncol} column labels")
    rows = []
    for lineno, line in body[1:]:
        fields = line.split()
        if len(fields) != ncol:
            raise StorageFileError(p, f"line {lineno + 1}: {len(fields)} values, expected {ncol}")
        try:
            rows.append([float(f) for f in fields])
        except ValueError:
            bad = next(j for j, f in enumerate(fields) if not _is_float(f))
            raise StorageFileError(p, f"line {lineno + 1}: value {fields[bad]!r} is not a number",
                                   column=labels[bad]) from None
    if not rows:
        raise StorageFileError(p, "the table has no data rows")
    data = np.array(rows, dtype=float)
    if n_rows is not None and n_rows != len(rows):
        raise StorageFileError(p, f"header says nRows={n_rows} but the table has {len(rows)} rows")
    finite = np.isfinite(data)
    if not finite.all():
        r, c = np.argwhere(~finite)[0]
        raise StorageFileError(p, f"non-finite value at data row {r + 1}", column=labels[c])
    t = data[:, 0]
    if len(t) > 1 and np.any(np.diff(t) <= 0):
        r = int(np.nonzero(np.diff(t) <= 0)[0][0])
        raise StorageFileError(p, f"times are not strictly increasing (data rows {r + 1}-{r + 2}: "
                                  f"{t[r]:.8g}, {t[r + 1]:.8g} s)", column=labels[0])
    return Storage(p, name, header, in_deg, tuple(labels[1:]), t.copy(), data[:, 1:].copy(), tuple(notes))


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True
