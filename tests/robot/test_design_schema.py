"""The design file's schema: every field's type and physical range, unknown and duplicate keys, YAML that
could exhaust memory, non-UTF-8 text — each refused with one line naming the file, the PAM and the field,
exit 2 from any command, never a traceback."""

from __future__ import annotations

import copy

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pamkin.cli import main
from pamkin.errors import DataFileError
from pamkin.robot.design import ROBOT_DESIGN, design_from_dict, load_design

BASE = yaml.safe_load(ROBOT_DESIGN.read_text())


def _write(tmp_path, data) -> str:
    f = tmp_path / "d.yaml"
    f.write_text(yaml.safe_dump(data, sort_keys=False) if not isinstance(data, str) else data)
    return str(f)


def _pam0(**changes) -> dict:
    d = copy.deepcopy(BASE)
    d["pams"][0].update(changes)
    return d


@pytest.mark.parametrize("data,match", [
    (_pam0(transmision=2), r"pams\[0\] \(id 1, 'Erector Spinae'\): unknown field 'transmision' \(did you mean "
                           r"'transmission'\?\)"),
    (_pam0(id="abc"), r"id must be an integer, is 'abc'"),
    (_pam0(cable_efficiency=1.2), r"pams\[0\] \(id 1, 'Erector Spinae'\): cable_efficiency must lie in \(0, 1\], "
                                  r"is 1.2"),
    (_pam0(cable_efficiency=0.0), r"cable_efficiency must lie in \(0, 1\], is 0.0"),
    (_pam0(cable_efficiency="0.9"), r"cable_efficiency must be a finite number, is '0.9'"),
    (_pam0(id=None), r"id must be an integer, is None"),
    (_pam0(n_parallel=1.7), r"n_parallel must be one of \(1, 2, 3\), is 1.7"),
    (_pam0(n_parallel="2"), r"n_parallel must be one of \(1, 2, 3\), is '2'"),
    (_pam0(diameter_mm=20.0), r"diameter_mm 20.0 is not a Festo DMSP size"),
    (_pam0(resting_length_m=1e6), r"resting_length_m must be a positive length in \[0.01, 2\] m, is 1000000.0"),
    (_pam0(resting_length_m=1e-9), r"resting_length_m must be a positive length in \[0.01, 2\] m"),
    (_pam0(human_muscles=["not_a_muscle_r"]), r"human_muscles: unknown name\(s\) \['not_a_muscle_r'\]"),
    (_pam0(points={"p1": [0, 0, 0]}), r"points must be a list of mappings"),
    (_pam0(points=["p1", "p2"]), r"points must be a list of mappings"),
    (_pam0(points=[{"name": "a", "body": "pelvis", "location": [5.0, 0, 0]},
                   {"name": "b", "body": "pelvis", "location": [0, 0, 0]}]), r"lies 5 m from its body's origin"),
    ({**BASE, "pams": None}, r"pams must be a non-empty list"),
    ({**BASE, "pams": 3}, r"pams must be a non-empty list"),
    ({**BASE, "pams": []}, r"pams must be a non-empty list"),
    ({**BASE, "pressure_Pa": 0}, r"pressure_Pa must lie in \[100000, 800000\], is 0"),
    ({**BASE, "pressure_Pa": 1e9}, r"pressure_Pa must lie in \[100000, 800000\]"),
    ({**BASE, "fitting_length_m": -0.01}, r"fitting_length_m must lie in \(0, 0.1\]"),
    ({**BASE, "force_model": "v99"}, r"force_model must be one of"),
    ({**BASE, "presure_Pa": 6e5}, r"unknown field 'presure_Pa' \(did you mean 'pressure_Pa'\?\)"),
])
def test_a_bad_field_is_named(tmp_path, data, match):
    path = _write(tmp_path, data)
    with pytest.raises(DataFileError, match=match) as e:
        load_design(path)
    assert str(e.value).startswith(path) and "\n" not in str(e.value)


@pytest.mark.parametrize("text,match", [
    ("name: x\npams: []\npams: []\n", r"duplicate key 'pams'"),
    ("a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\nc: [*b, *b, *b]\npams: []\n",
     r"anchors and aliases"),
])
def test_yaml_that_hides_or_explodes_is_refused(tmp_path, text, match):
    with pytest.raises(DataFileError, match=match):
        load_design(_write(tmp_path, text))


@pytest.mark.parametrize("raw", [b"name: \xff\xfe\n", "name: x\npams: []\n".encode("utf-16")])
def test_non_utf8_is_refused(tmp_path, raw):
    f = tmp_path / "d.yaml"
    f.write_bytes(raw)
    with pytest.raises(DataFileError, match="not UTF-8 text"):
        load_design(f)


def test_every_command_exits_2_with_one_line(tmp_path, capsys):
    path = _write(tmp_path, _pam0(transmision=2))
    for argv in (["audit", path, "--quick"], ["gait", path], ["view", "--design", path, "--html",
                                                              str(tmp_path / "v.html"), "--no-meshes"],
                 ["compare", "--design", path], ["export-osim", path, "--out", str(tmp_path / "x.osim")]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "unknown field 'transmision'" in err and "Traceback" not in err and err.count("\n") == 1, argv
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.yaml"]


_FIELDS = ["id", "name", "human_muscles", "primary_coordinate", "secondary_coordinates", "diameter_mm",
           "n_parallel", "resting_length_m", "tendon_length_m", "notes", "points", "transmission", "pam_at"]
_VALUES = st.one_of(st.none(), st.booleans(), st.integers(-10**9, 10**9), st.floats(allow_nan=True),
                    st.text(max_size=8), st.lists(st.integers(), max_size=3),
                    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, 26), st.sampled_from(_FIELDS), _VALUES), min_size=1, max_size=3))
def test_mutated_designs_load_or_are_refused_by_name(mutations):
    """Property: any design with fields replaced by values of any type either loads or raises DataFileError
    (never another exception)."""
    data = copy.deepcopy(BASE)
    for k, field, value in mutations:
        data["pams"][k][field] = value
    try:
        design_from_dict(data, "mutated.yaml")
    except DataFileError as e:
        assert str(e).startswith("mutated.yaml: ")


def test_cable_efficiency_round_trip(tmp_path):
    """``cable_efficiency`` is written only where it is not 1 and read back exactly."""
    from pamkin.robot.design import save_design

    d = _pam0(cable_efficiency=0.875)
    des = design_from_dict(d, "d.yaml")
    assert des.pams[0].cable_efficiency == 0.875 and des.pams[1].cable_efficiency == 1.0
    again = load_design(save_design(des, tmp_path / "again.yaml"))
    assert again.pams[0].cable_efficiency == 0.875
    out = again.to_dict()["pams"]
    assert out[0]["cable_efficiency"] == 0.875 and "cable_efficiency" not in out[1]
