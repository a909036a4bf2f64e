"""The one output layer: every file pamkin writes goes through here, so that nothing a user has is lost.

Rules (the documentation's "Inputs and outputs" page):

* A regular file (or a new path) is written atomically: a uniquely named temporary file in the target's own
  folder, then ``os.replace``; a failure leaves the old file as it was and removes the temporary file.
* A symbolic link is written through: its target is written (atomically, as above), the link stays a link.
* A named pipe, a character device or a socket is written through, never replaced: the data is written into
  it as into any open file (``/dev/stdout``, a FIFO another program reads).
* A folder where a file is asked for, or a file whose folder is a file, is refused with an error naming the
  path (:class:`pamkin.errors.OutputError`, exit 2) — by :func:`check_output_file`, before any work.
* Outputs of several files (a report, an audit folder) are built in a temporary sibling folder and put in
  place whole (:func:`output_folder`): they appear complete or not at all. An existing folder is refused unless
  ``force`` is given, which replaces it whole (no stale files of the old output remain).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from pamkin.errors import OutputError

__all__ = ["check_output_file", "check_output_folder", "output_folder", "strict_json", "write_figure", "write_file"]


def _special(path: Path) -> bool:
    """``path`` exists and is a pipe, a device or a socket (written through, never replaced)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return stat.S_ISFIFO(mode) or stat.S_ISCHR(mode) or stat.S_ISBLK(mode) or stat.S_ISSOCK(mode)


def check_output_file(path: str | os.PathLike) -> Path:
    """Check, before any work, that ``path`` can take a file: not a folder, its folder not a file.

    Returns:
        The path (a symbolic link resolved to its target, which is what gets written).

    Raises:
        OutputError: naming the path.
    """
    path = Path(path)
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    if path.is_dir():
        raise OutputError(str(path), "is a folder; give a file name")
    parent = path.parent
    for folder in (parent, *parent.parents):
        if folder.exists():
            if not folder.is_dir():
                raise OutputError(str(path), f"{folder} is not a folder")
            break
    return path


def write_file(path: str | os.PathLike, data: str | bytes) -> Path:
    """Write ``data`` (text as UTF-8) to ``path`` by the rules of this module; folders are created.

    Returns:
        The path written (a symbolic link's target).
    """
    path = check_output_file(path)
    raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    if _special(path):
        with open(path, "wb") as f:         # a pipe or a device: written through, never replaced
            f.write(raw)
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
        os.chmod(tmp, _mode(path))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _mode(path: Path) -> int:
    """The permissions a file written at ``path`` gets: those of the file it replaces, else 0644."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o644


def write_figure(fig, path: str | os.PathLike, **savefig) -> Path:
    """A matplotlib figure saved to ``path`` (format from its suffix) through :func:`write_file`."""
    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format=(path.suffix.lstrip(".") or "png"), **savefig)
    return write_file(path, buf.getvalue())


def check_output_folder(path: str | os.PathLike, force: bool = False) -> Path:
    """Check, before any work, that ``path`` can take a multi-file output: absent, an empty folder, or an
    existing one with ``force``.

    Raises:
        OutputError: naming the path (a file, or a folder with files and no ``force``).
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(str(path), "exists and is not a folder")
    if path.is_dir() and any(path.iterdir()) and not force:
        raise OutputError(str(path), "holds files already; choose a new folder, or --force to replace it whole")
    for folder in path.parents:
        if folder.exists():
            if not folder.is_dir():
                raise OutputError(str(path), f"{folder} is not a folder")
            break
    return path


@contextlib.contextmanager
def output_folder(path: str | os.PathLike, force: bool = False) -> Iterator[Path]:
    """A multi-file output: yields a temporary sibling folder to write into; on success it replaces ``path``
    whole (with ``force``, an existing folder is removed only then), on failure it is removed and ``path`` is
    left as it was.

    Raises:
        OutputError: as :func:`check_output_folder`.
    """
    path = check_output_folder(path, force)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.", suffix=".partial"))
    try:
        yield tmp
        os.chmod(tmp, 0o755)
        old = None
        if path.exists():
            old = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.", suffix=".old"))
            os.replace(path, old / path.name)
        os.replace(tmp, path)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _finite(x):
    if isinstance(x, dict):
        return {str(k): _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if hasattr(x, "tolist") and not isinstance(x, (str, bytes)):      # numpy arrays and scalars
        return _finite(x.tolist())
    if isinstance(x, float):
        return x if x == x and x not in (float("inf"), float("-inf")) else None
    return x


def strict_json(obj, indent: int | None = 2) -> str:
    """``obj`` as strict JSON text: every non-finite number (an undefined error, a failed solve's objective)
    is ``null``, numpy values are plain numbers — what every JSON reader accepts."""
    return json.dumps(_finite(obj), indent=indent, allow_nan=False)
