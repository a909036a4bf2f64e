"""pamkin.yamlio: the C-parser loader reads the project's data files exactly as PyYAML's safe loader."""

from __future__ import annotations

import pytest
import yaml

from pamkin._resources import ROBOT_DIR
from pamkin.yamlio import safe_load


@pytest.mark.parametrize("name", sorted(p.name for p in (ROBOT_DIR / "data").glob("*.yaml")))
def test_same_objects_as_pure_python_safe_load(name):
    text = (ROBOT_DIR / "data" / name).read_text()
    assert safe_load(text) == yaml.load(text, Loader=yaml.SafeLoader)


def test_unsafe_tags_and_malformed_text_are_yaml_errors():
    with pytest.raises(yaml.YAMLError):
        safe_load("a: !!python/object/apply:os.system ['true']\n")
    with pytest.raises(yaml.YAMLError):
        safe_load("a: [1, 2\nb: 3\n")
