"""OpenSim storage files (.mot/.sto): the shared walking trial and malformed copies."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pamkin.cli import main
from pamkin.errors import DataFileError, StorageFileError
from pamkin.gait.plan import DEFAULT_GRF, DEFAULT_ID, DEFAULT_IK
from pamkin.opensim.storage import read_storage

needs_trial = pytest.mark.skipif(not DEFAULT_IK.exists(), reason=f"shared gait data not found at {DEFAULT_IK}")

TOY = """toy
version=1
nRows=3
nColumns=3
inDegrees=yes
endheader
time\tknee_angle_r\tpelvis_tx
0.0\t0.0\t1.0
0.1\t90.0\t2.0
0.3\t180.0\t4.0
"""


def _write(tmp_path: Path, text: str, name: str = "f.mot") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.needs_shared
@needs_trial
def test_shared_ik_file():
    s = read_storage(DEFAULT_IK)
    assert s.name == "Coordinates"
    assert s.in_degrees is True
    assert s.header["nRows"] == "211" and s.header["nColumns"] == "24"
    assert len(s) == 211 and len(s.columns) == 23
    assert s.time[0] == pytest.approx(0.5) and s.time[-1] == pytest.approx(4.0)
    assert np.allclose(np.diff(s.time), 1 / 60, atol=1e-7)
    assert s.columns[:2] == ("pelvis_tilt", "pelvis_list") and s.columns[-1] == "lumbar_rotation"
    assert s.column("hip_flexion_r")[0] == pytest.approx(19.18693645)
    assert "Angles are in degrees." in s.notes


@pytest.mark.needs_shared
@needs_trial
def test_shared_id_and_grf_files():
    s = read_storage(DEFAULT_ID)
    assert s.name == "Inverse Dynamics" and s.in_degrees is False
    assert len(s) == 73 and len(s.columns) == 23
    assert all(c.endswith(("_moment", "_force")) for c in s.columns)
    assert [c for c in s.columns if c.endswith("_force")] == ["pelvis_tx_force", "pelvis_ty_force", "pelvis_tz_force"]
    assert s.time[0] == pytest.approx(0.39999934) and s.time[-1] == pytest.approx(1.59999886)
    assert s.column("knee_angle_r_moment")[0] == pytest.approx(21.14172236)
    g = read_storage(DEFAULT_GRF)         # header lines end in tabs
    assert g.header["nRows"] == "1501" and len(g) == 1501 and len(g.columns) == 18
    assert "1_ground_force_vy" in g


def test_toy_file_values_units_and_interpolation(tmp_path):
    s = read_storage(_write(tmp_path, TOY))
    assert s.columns == ("knee_angle_r", "pelvis_tx")
    assert np.allclose(s.values(["pelvis_tx", "knee_angle_r"])[1], [2.0, 90.0])
    q = s.coordinates_si(["knee_angle_r", "pelvis_tx"], [True, False])
    assert q[1, 0] == pytest.approx(math.pi / 2) and q[1, 1] == 2.0     # degrees converted, metres kept
    v = s.interpolate([0.05, 0.2, 0.30005], ["knee_angle_r", "pelvis_tx"])
    assert np.allclose(v, [[45.0, 1.5], [135.0, 3.0], [180.0, 4.0]])
    with pytest.raises(StorageFileError, match="outside the file's time range"):
        s.interpolate([0.31], ["pelvis_tx"])
    rad = read_storage(_write(tmp_path, TOY.replace("inDegrees=yes", "inDegrees=no"), "r.mot"))
    assert rad.coordinates_si(["knee_angle_r"], [True])[1, 0] == 90.0   # radians: as stored
    none = read_storage(_write(tmp_path, TOY.replace("inDegrees=yes\n", ""), "n.mot"))
    assert none.in_degrees is None
    with pytest.raises(StorageFileError, match="no inDegrees"):
        none.coordinates_si(["knee_angle_r"], [True])


def test_unknown_column_names_file_and_column(tmp_path):
    p = _write(tmp_path, TOY)
    s = read_storage(p)
    with pytest.raises(StorageFileError) as e:
        s.column("knee_angle_l")
    assert e.value.column == "knee_angle_l" and e.value.path == str(p)
    assert str(p) in str(e.value) and "knee_angle_l" in str(e.value) and "did you mean" in str(e.value)
    assert isinstance(e.value, DataFileError)
    with pytest.raises(StorageFileError, match="'hip'"):
        s.values(["knee_angle_r", "hip"])


@pytest.mark.parametrize("edit, match", [
    (lambda t: t.replace("endheader\n", ""), "no 'endheader'"),
    (lambda t: t.replace("nRows=3", "nRows=4"), "nRows=4 but the table has 3 rows"),
    (lambda t: t.replace("nColumns=3", "nColumns=5"), "nColumns=5 but the table has 3"),
    (lambda t: t.replace("nRows=3", "nRows=three"), "not an integer"),
    (lambda t: t.replace("inDegrees=yes", "inDegrees=maybe"), "expected 'yes' or 'no'"),
    (lambda t: t.replace("0.1\t90.0\t2.0", "0.1\t90.0"), "line 9: 2 values, expected 3"),
    (lambda t: t.replace("0.1\t90.0\t2.0", "0.1\tninety\t2.0"), "'knee_angle_r'.*'ninety' is not a number"),
    (lambda t: t.replace("0.1\t90.0\t2.0", "0.1\tnan\t2.0"), "'knee_angle_r'.*non-finite"),
    (lambda t: t.replace("time\t", "t\t"), "first column must be 'time'"),
    (lambda t: t.replace("pelvis_tx\n", "knee_angle_r\n"), "duplicate column label"),
    (lambda t: t.replace("0.3\t", "0.1\t"), "not strictly increasing"),
    (lambda t: t.split("time")[0], "no column labels"),
    (lambda t: t.split("0.0\t")[0], "no data rows"),
])
def test_malformed_copies(tmp_path, edit, match):
    p = _write(tmp_path, edit(TOY))
    with pytest.raises(StorageFileError, match=match) as e:
        read_storage(p)
    assert str(e.value).startswith(str(p))


def test_missing_file(tmp_path):
    with pytest.raises(StorageFileError, match="file not found"):
        read_storage(tmp_path / "nope.mot")


@pytest.mark.needs_shared
@needs_trial
def test_malformed_shared_copies(tmp_path):
    ik = DEFAULT_IK.read_text().splitlines(keepends=True)
    bad = tmp_path / "ik_ragged.mot"
    end = next(i for i, line in enumerate(ik) if line.strip() == "endheader")
    ik_bad = ik.copy()
    ik_bad[end + 5] = "\t".join(ik_bad[end + 5].split()[:-1]) + "\n"
    bad.write_text("".join(ik_bad))
    with pytest.raises(StorageFileError, match=f"line {end + 6}: 23 values, expected 24"):
        read_storage(bad)
    cut = tmp_path / "ik_cut.mot"
    cut.write_text("".join(ik[:-10]))
    with pytest.raises(StorageFileError, match="nRows=211 but the table has 201 rows"):
        read_storage(cut)


@pytest.mark.needs_shared
@needs_trial
def test_cli_reports_malformed_file(tmp_path, capsys):
    bad = tmp_path / "bad.sto"
    bad.write_text(DEFAULT_ID.read_text().replace("knee_angle_r_moment", "knee_r_moment"))
    assert main(["gait", "thesis", "--id", str(bad), "--grf", "none"]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "knee_angle_r_moment" in err and "pamkin gait: error" in err
