"""A run folder's store of finished tasks: what makes a killed run resumable.

Every per-actuator task a stage runs (:func:`optimize.executor.map_tasks`) is saved, as soon as it finishes,
to ``RUN/tasks/<stage call>/<task key>.pkl`` (pickle, written atomically: a temporary file in the same
folder, then renamed). The key is a hash of the task itself (actuator index, size, start vector), so a
resumed run — the same seed, config and code, hence the same tasks in the same order — finds every task its
killed predecessor finished and solves only the rest. The run's configuration is kept beside them
(``RUN/config.json``): ``pamkin optimize --resume RUN`` reads it back.

Pickles execute code when loaded: resume only run folders you (or your runs) wrote.
"""

from __future__ import annotations

import hashlib
import os
import pickle
from pathlib import Path

from pamkin.outputs import write_file

#: Sub-folder of a run folder holding the finished tasks.
TASKS_DIR = "tasks"


def task_key(task) -> str:
    """A stable name of a task (a hash of its pickled form)."""
    return hashlib.sha256(pickle.dumps(task, protocol=4)).hexdigest()[:24]


class RunStore:
    """Finished tasks of the run in ``folder`` (created on the first save)."""

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder) / TASKS_DIR
        self.calls: dict[str, int] = {}

    def _path(self, label: str, task) -> Path:
        return self.folder / label / f"{task_key(task)}.pkl"

    def load(self, label: str, task):
        """The stored result of ``task`` under ``label``, or None."""
        path = self._path(label, task)
        if not path.is_file():
            return None
        try:
            return pickle.loads(path.read_bytes())
        except (pickle.UnpicklingError, EOFError, AttributeError, ImportError):
            return None          # written by another pamkin version, or cut short: solved again

    def save(self, label: str, task, result) -> None:
        """Store ``result`` of ``task`` under ``label`` (atomically, :func:`pamkin.outputs.write_file`)."""
        write_file(self._path(label, task), pickle.dumps(result, protocol=4))

    def stored(self) -> int:
        """How many finished tasks the folder holds."""
        return sum(1 for _ in self.folder.rglob("*.pkl")) if self.folder.is_dir() else 0
