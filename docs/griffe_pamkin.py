"""Griffe extension for the API reference: read ``optimize/`` as ``pamkin.optimize``.

pyproject.toml installs the repository folder ``optimize/`` as the subpackage ``pamkin.optimize``
(``[tool.setuptools.package-dir]``). Griffe reads the source tree, where ``pamkin/`` has no ``optimize``
folder, so ``::: pamkin.optimize`` would not be found; this extension loads ``optimize/`` beside
``pamkin/`` and attaches it to ``pamkin`` under that name (paths such as ``pamkin.optimize.config`` then
resolve as in the installed package).

Registered in ``mkdocs.yml`` under the python handler's ``extensions``.
"""

from __future__ import annotations

from pathlib import Path

import griffe


class PamkinOptimize(griffe.Extension):
    """Attach the repository's ``optimize/`` package to ``pamkin`` as ``pamkin.optimize``."""

    def on_package(self, *, pkg: griffe.Module, loader: griffe.GriffeLoader, **kwargs) -> None:
        if pkg.name != "pamkin" or "optimize" in pkg.members or pkg.filepath is None:
            return
        root = Path(pkg.filepath if isinstance(pkg.filepath, Path) else pkg.filepath[0]).parent.parent
        if not (root / "optimize" / "__init__.py").is_file():
            return
        sub = griffe.load(
            "optimize",
            search_paths=[root],
            docstring_parser=loader.docstring_parser,
            docstring_options=loader.docstring_options,
            try_relative_path=False,
        )
        pkg.set_member("optimize", sub)
