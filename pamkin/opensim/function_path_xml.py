"""Writing ``FunctionBasedPath``s into an OpenSim model file.

:func:`with_function_paths` takes an ``.osim`` file and a function-based path per muscle and returns the
file's text with each of those muscles' ``<GeometryPath>`` replaced by a ``<FunctionBasedPath>`` (OpenSim
4.5+; OpenSim 4.6 loads and simulates it). Everything else in the file stays as it was. Numbers are
written with 17 significant digits: the file holds the functions exactly.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

from pamkin.errors import OsimError
from pamkin.opensim.functions import (
    Constant,
    LinearFunction,
    MultivariatePolynomial,
    OneVariable,
    PolynomialFunction,
    SimmSpline,
)
from pamkin.opensim.model_file import FunctionPath, OsimModel


def _numbers(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def function_element(fn) -> ET.Element:
    """The XML element of an OpenSim function (the types pamkin writes)."""
    if isinstance(fn, OneVariable):
        return function_element(fn.function)
    if isinstance(fn, MultivariatePolynomial):
        el = ET.Element("MultivariatePolynomialFunction")
        ET.SubElement(el, "coefficients").text = _numbers(fn.coefficients)
        ET.SubElement(el, "dimension").text = str(fn.dimension)
        ET.SubElement(el, "order").text = str(fn.order)
        return el
    if isinstance(fn, SimmSpline):
        el = ET.Element("SimmSpline")
        ET.SubElement(el, "x").text = _numbers(fn.x)
        ET.SubElement(el, "y").text = _numbers(fn.y)
        return el
    if isinstance(fn, Constant):
        el = ET.Element("Constant")
        ET.SubElement(el, "value").text = repr(float(fn.c))
        return el
    if isinstance(fn, LinearFunction):
        el = ET.Element("LinearFunction")
        ET.SubElement(el, "coefficients").text = _numbers((fn.slope, fn.intercept))
        return el
    if isinstance(fn, PolynomialFunction):
        el = ET.Element("PolynomialFunction")
        ET.SubElement(el, "coefficients").text = _numbers(fn.coefficients)
        return el
    raise TypeError(f"cannot write function {fn!r} to an OpenSim file")


def function_path_element(path: FunctionPath, model: OsimModel) -> ET.Element:
    """``<FunctionBasedPath name="path">`` for ``path`` (coordinates named by their component paths)."""
    el = ET.Element("FunctionBasedPath", name="path")
    coords = [model.coordinate(c) for c in path.coordinates]
    ET.SubElement(el, "coordinate_paths").text = " ".join(f"/jointset/{c.joint}/{c.name}" for c in coords)
    ET.SubElement(el, "length_function").append(function_element(path.length))
    if path.moment_arms:
        arms = ET.SubElement(el, "moment_arm_functions")
        for f in path.moment_arms:
            arms.append(function_element(f))
    return el


def with_function_paths(source: str | Path, model: OsimModel, paths: dict[str, FunctionPath]) -> str:
    """The text of ``source`` with the named muscles' geometry paths replaced by function-based paths.

    The rest of the file is kept byte for byte (the replaced ``<GeometryPath>`` elements are cut out of the
    text and the new elements put in their place).

    Args:
        source: The ``.osim`` file ``model`` was read from.
        model: The model read from it (for the coordinates' joints).
        paths: ``{muscle name: FunctionPath}``.

    Raises:
        OsimError: A named muscle is not in the file's ForceSet or has no ``<GeometryPath>``.
    """
    text = Path(source).read_bytes().decode("utf-8")
    lo = text.find("<ForceSet")
    hi = text.find("</ForceSet>", lo)
    if lo < 0 or hi < 0:
        raise OsimError(str(source), "has no <ForceSet>", element="Model")
    cuts = []
    missing = []
    for name, path in paths.items():
        m = re.search(rf'<(\w+)\s+name="{re.escape(name)}"\s*>', text[lo:hi])
        if m is None:
            missing.append(name)
            continue
        start = lo + m.start()
        end = text.find(f"</{m.group(1)}>", start)
        a = text.find("<GeometryPath", start, end)
        b = text.find("</GeometryPath>", a, end)
        if a < 0 or b < 0:
            raise OsimError(str(source), "has no <GeometryPath> to replace", element=m.group(1), component=name)
        indent = text[text.rfind("\n", 0, a) + 1:a]
        cuts.append((a, b + len("</GeometryPath>"), _element_text(function_path_element(path, model), indent)))
    if missing:
        raise OsimError(str(source), f"no force named {', '.join(map(repr, missing))} in the ForceSet",
                        element="ForceSet")
    for a, b, new in sorted(cuts, reverse=True):
        text = text[:a] + new + text[b:]
    return text


def _element_text(el: ET.Element, indent: str) -> str:
    """``el`` as indented XML text whose first line starts at the cursor and later lines at ``indent``."""
    ET.indent(el, space="\t")
    return ET.tostring(el, encoding="unicode").replace("\n", "\n" + indent)
