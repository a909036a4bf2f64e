"""Ranges of motion (coupled hip limits), grids, muscle groups and the torque CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pamkin.cli import main
from pamkin.errors import ConfigurationError, DataFileError
from pamkin.human.groups import load_groups
from pamkin.human.rom import load_rom


def test_robot_hip_adduction_limits_follow_flexion():
    rom = load_rom("robot_thesis", "r")
    lo, hi = rom.bounds("hip_adduction_r", {"hip_flexion_r": np.radians([-15.0, 110.0, 47.5])})
    # thesis: at max flexion adduction in [-60, +10] deg, at max extension in [-10, +20] deg
    assert np.allclose(np.degrees(lo), [-10.0, -60.0, -35.0])
    assert np.allclose(np.degrees(hi), [20.0, 10.0, 15.0])
    assert rom.limits["hip_flexion_r"] == pytest.approx(tuple(np.radians([-15, 110])))


def test_grid_sweeps_coupled_coordinate_within_limits():
    rom = load_rom("robot_thesis", "l")
    g = rom.grid(["hip_flexion_l", "hip_adduction_l"], n=[5, 7])
    assert g.shape == (35, 2)
    assert rom.contains(["hip_flexion_l", "hip_adduction_l"], g).all()
    first = g[:7]   # flexion fixed at -15 deg: adduction from -10 to +20
    assert np.allclose(np.degrees(first[:, 1]), np.linspace(-10, 20, 7))
    assert not rom.contains(["hip_flexion_l", "hip_adduction_l"], np.radians([[110.0, 15.0]])).any()


def test_grid_needs_its_dependency():
    rom = load_rom("robot_thesis")
    with pytest.raises(ConfigurationError, match="hip_flexion_r"):
        rom.grid(["hip_adduction_r"], 3)


def test_unknown_rom_name():
    with pytest.raises(DataFileError, match="robot_thesis"):
        load_rom("robot_2019")


def test_model_grid_nd(gait2392):
    q, shape = gait2392.grid(["hip_flexion_r", "knee_angle_r", "ankle_angle_r"], n=[3, 4, 5])
    assert shape == (3, 4, 5) and q.shape == (60, 23)
    T = gait2392.torques(q).reshape(*shape, 92, 23)
    assert T.shape == (3, 4, 5, 92, 23)
    with pytest.raises(ConfigurationError, match="knee_x"):
        gait2392.grid(["knee_x"], 3)


def test_groups_cover_the_actuator_map(gait2392):
    groups = load_groups()
    act = [g for g in groups if g.kind == "actuator"]
    assert len(act) == 54 and {g.actuator_id for g in act} == set(range(1, 28))
    for g in groups:
        assert set(g.muscles) <= set(gait2392.muscles), g.key
        if g.kind == "actuator":
            assert g.primary_coordinate in gait2392.coordinates
    vasti = next(g for g in act if g.key == "act11_l")
    assert vasti.muscles == ("vas_int_l", "vas_lat_l", "vas_med_l")
    thesis_r = [g for g in groups if g.kind == "thesis" and g.side == "r"]
    covered = {m for g in thesis_r for m in g.muscles}
    assert covered == {m for m in gait2392.muscles if m.endswith("_r")}   # every right muscle in a group


def test_torques_cli_json(capsys):
    assert main(["torques", "--coords", "knee_angle", "-n", "5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_configurations"] == 5
    vasti = out["groups_Nm"]["act11_r"]["knee_angle_r"]
    assert vasti[0] > 0          # knee extensors
    assert out["capacity_Nm"]["knee_angle_r"]["max_positive"] >= vasti[1]


def test_cli_reports_bad_coordinate(capsys):
    assert main(["torques", "--coords", "elbow"]) == 2
    assert "unknown coordinate 'elbow'" in capsys.readouterr().err
