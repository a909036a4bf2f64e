"""Exception tree of pamkin.

Every error names what it is about (file, element, component, coordinate,
muscle) so that a user can find the offending input.
"""

from __future__ import annotations


class PamkinError(Exception):
    """Base class of every error raised by pamkin."""

    def __reduce__(self):
        # picklable whatever the subclass's __init__ takes (an error raised in a worker process reaches
        # the parent intact: its message, type and attributes)
        return _rebuild_error, (type(self), self.args, dict(self.__dict__))


def _rebuild_error(cls: type, args: tuple, state: dict) -> PamkinError:
    """A pamkin error from its pickled parts (see :meth:`PamkinError.__reduce__`)."""
    err = cls.__new__(cls)
    Exception.__init__(err, *args)
    err.__dict__.update(state)
    return err


class OsimError(PamkinError):
    """A problem in an OpenSim ``.osim`` file.

    Attributes:
        path: The file.
        element: The XML element type (e.g. ``"CustomJoint"``), if known.
        component: The ``name`` of the offending component, if known.
    """

    def __init__(self, path: str, message: str, *, element: str | None = None,
                 component: str | None = None) -> None:
        self.path = str(path)
        self.element = element
        self.component = component
        where = self.path
        if element is not None:
            where += f": <{element}"
            where += f' name="{component}">' if component is not None else ">"
        elif component is not None:
            where += f": {component}"
        super().__init__(f"{where}: {message}")


class UnsupportedFeatureError(OsimError):
    """The ``.osim`` file uses an OpenSim feature pamkin does not implement."""


class ConfigurationError(PamkinError, ValueError):
    """A configuration array (coordinates) is malformed: wrong shape, NaN, unknown names."""


class RangeWarning(UserWarning):
    """Coordinates lie outside the model's ranges (values are used as given, never clamped)."""


class EquilibriumWarning(UserWarning):
    """No static muscle equilibrium exists for some (configuration, muscle) pairs (OpenSim raises
    ``MuscleCannotEquilibrate`` there); pamkin returns NaN forces for them."""


class ParameterError(PamkinError, ValueError):
    """A physical parameter is out of range (e.g. a negative optimal fibre length)."""


class DataFileError(PamkinError):
    """A project data file (YAML/JSON/TOML design or parameter file) is malformed."""

    def __init__(self, path: str, message: str) -> None:
        self.path = str(path)
        super().__init__(f"{self.path}: {message}")


class StorageFileError(DataFileError):
    """An OpenSim storage file (``.mot``/``.sto``) is malformed, or lacks a requested column.

    Attributes:
        path: The file.
        column: The offending column, if any.
    """

    def __init__(self, path: str, message: str, *, column: str | None = None) -> None:
        self.column = column
        super().__init__(path, f"column {column!r}: {message}" if column is not None else message)


class SolverError(PamkinError):
    """A numerical solver (e.g. a QP solver) failed on a well-posed problem; names the problem."""


class BuildError(PamkinError):
    """Generating a URDF from Xacro sources failed."""


class OutputError(PamkinError):
    """An output path that cannot take what is to be written there (a folder for a file, an existing run or
    report folder); raised before any work, so nothing is computed for nothing and nothing is lost."""

    def __init__(self, path: str, message: str) -> None:
        self.path = str(path)
        super().__init__(f"{self.path}: {message}")
