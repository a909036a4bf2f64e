"""``pamkin mjcf``: writes a folder MuJoCo loads, with its measurement; refuses bad input and existing folders."""

from __future__ import annotations

import json

import mujoco

from pamkin.cli import main


def test_mjcf_design_writes_a_loadable_folder_with_errors(tmp_path, capsys):
    out = tmp_path / "robot_mjcf"
    assert main(["mjcf", "--design", "robot", "--out", str(out), "--measure", "20"]) == 0
    m = mujoco.MjModel.from_xml_path(str(out / "model.xml"))
    assert m.ntendon > 0 and m.nmesh > 0
    summary = json.loads((out / "errors.json").read_text())
    assert summary["poses"] == 20 and summary["exact"] >= 20 and summary["exact_length_max_m"] < 1e-6
    assert (out / "errors.png").stat().st_size > 1000
    rows = (out / "errors.csv").read_text().splitlines()
    conv = json.loads((out / "conversion.json").read_text())
    composed = [t for t in conv["tied_joints"] if "composed_terms" in t]   # each a fixed tendon
    assert rows[0].startswith("path,length_max_mm") and len(rows) == m.ntendon - len(composed) + 1
    assert conv["couplings"] == "composed" and len(composed) == 12   # knee translations, patella points
    assert conv["tied_joints"] and all(t["max_error"] < 2e-3 for t in conv["tied_joints"])
    assert all(t["max_error"] < 5e-5 for t in composed)
    assert "wrote" in capsys.readouterr().out
    # an existing folder is refused before any work, and kept
    before = sorted(p.name for p in out.iterdir())
    assert main(["mjcf", "--design", "robot", "--out", str(out)]) == 2
    assert "holds files already" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == before


def test_mjcf_bad_model_file_is_a_clear_error(tmp_path, capsys):
    bad = tmp_path / "broken.osim"
    bad.write_text("<OpenSimDocument><Model name='x'><BodySet><objects><Body name='b'>")
    assert main(["mjcf", "--osim", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "broken.osim" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()
    assert main(["mjcf", "--measure", "-1", "--out", str(tmp_path / "o")]) == 2
