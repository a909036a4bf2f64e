"""Write a conversion: ``model.xml``, ``meshes/*.stl``, ``conversion.json`` and, when measured, the errors."""

from __future__ import annotations

import os
from pathlib import Path

from pamkin.outputs import output_folder, strict_json, write_figure, write_file
from pamkin.sim.convert import Conversion
from pamkin.sim.geometry import GeometryErrors
from pamkin.sim.measure import error_figure, errors_csv, exact_constructs, summary


def write_conversion(conv: Conversion, folder: str | os.PathLike, force: bool = False,
                     errors: GeometryErrors | None = None, poses: int = 0) -> Path:
    """Write the conversion into a new folder (refused when it exists unless ``force``; written whole or not
    at all): ``model.xml`` (MuJoCo loads it with its meshes), ``meshes/*.stl``, ``conversion.json`` (joint
    polynomials with their largest deviation, the construct chosen per path) and, with ``errors`` measured on
    ``poses`` poses, ``errors.csv``, ``errors.json`` and ``errors.png``."""
    with output_folder(folder, force) as tmp:
        write_file(tmp / "model.xml", conv.mjcf())
        for rel, data in conv.meshes.items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            write_file(tmp / rel, data)
        write_file(tmp / "conversion.json", strict_json(conv.summary()))
        if errors is not None:
            write_file(tmp / "errors.csv", errors_csv(errors, conv))
            write_file(tmp / "errors.json", strict_json({"poses": poses, **summary(errors, exact_constructs(conv))}))
            write_figure(error_figure(errors, f"{conv.name}: MuJoCo vs pamkin on {poses} random poses"),
                         tmp / "errors.png", dpi=110)
    return Path(folder)
