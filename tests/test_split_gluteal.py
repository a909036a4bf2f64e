"""The split-gluteal seed design (tools/make_split_gluteal.py): the thesis layout with actuator 24's nine
gluteal muscles shared between gluteus maximus (24) and gluteus medius/minimus (28)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from pamkin import gait
from pamkin.design import SPLIT_GLUTEAL_DESIGN, load_design

ROOT = Path(__file__).resolve().parents[1]


def test_split_design_partitions_the_gluteal_group():
    thesis, split = load_design("thesis"), load_design("split_gluteal")
    assert split.path == str(SPLIT_GLUTEAL_DESIGN)
    assert [p.id for p in split.pams] == list(range(1, 29))
    g24, g28 = split.pam(24), split.pam(28)
    assert set(g24.human_muscles) == {"glut_max1_r", "glut_max2_r", "glut_max3_r"}
    assert set(g24.human_muscles) | set(g28.human_muscles) == set(thesis.pam(24).human_muscles)
    assert not set(g24.human_muscles) & set(g28.human_muscles)
    assert g28.primary_coordinate == "hip_adduction_r"
    assert g24.points == thesis.pam(24).points
    for p in thesis.pams:                    # everything else is the thesis design
        if p.id != 24:
            assert split.pam(p.id) == p


def test_split_design_file_is_up_to_date():
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "make_split_gluteal.py"), "--check"],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.skipif(not gait.DEFAULT_IK.is_file(), reason="walking trial (../shared/gait) not available")
def test_splitting_the_gluteal_group_lets_the_thesis_robot_walk_more_of_the_trial():
    """One lumped PAM cannot abduct the hip in single stance without extending and rotating it: with
    the thesis routes unchanged, the split alone raises the feasible frames from 33 of 67 to 43."""
    thesis = gait.gait_plan("thesis")
    split = gait.gait_plan("split_gluteal")
    assert round(67 * thesis.feasible_frame_fraction) == 33
    assert round(67 * split.feasible_frame_fraction) == 43
    hip_l = [c for c in split.coordinate_results if c.name == "hip_adduction_l"][0]
    hip_l_thesis = [c for c in thesis.coordinate_results if c.name == "hip_adduction_l"][0]
    assert hip_l.within_tolerance_fraction > hip_l_thesis.within_tolerance_fraction + 0.1
