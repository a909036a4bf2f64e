"""Every Python package of the source tree is in the wheel (pyproject's explicit package list)."""

from __future__ import annotations

import tomllib

from locations import ROOT


def test_every_subpackage_is_listed_in_pyproject():
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(cfg["packages"])
    dirs = {v: k for k, v in cfg["package-dir"].items()}          # folder -> package name
    found = set()
    for top in ("pamkin", "optimize"):
        for init in (ROOT / top).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT).as_posix()
            head, _, rest = rel.partition("/")
            name = dirs.get(head, head) + ("." + rest.replace("/", ".") if rest else "")
            found.add(name)
    assert found - listed == set(), f"packages missing from pyproject's list: {sorted(found - listed)}"
