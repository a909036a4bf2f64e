"""The merged seed design (tools/make_merged_seed.py): the v2 seed with synergists merged into 22 PAMs per
side, every muscle still assigned to exactly one PAM."""

from __future__ import annotations

import subprocess
import sys
from collections import Counter

from pamkin.robot.design import load_design
from locations import ROOT

MERGED = ROOT / "robot" / "data" / "merged_seed_design.yaml"


def test_merged_seed_assigns_every_muscle_of_the_v2_seed_exactly_once():
    seed, merged = load_design("v2_seed"), load_design("merged_seed")
    assert merged.path == str(MERGED)
    assert len(merged.pams) == 22
    count = Counter(m for p in merged.pams for m in p.human_muscles)
    assert set(count) == {m for p in seed.pams for m in p.human_muscles} and set(count.values()) == {1}
    assert merged.pam(26).human_muscles == ("iliacus_r", "psoas_r")
    assert set(merged.pam(5).human_muscles) == {"semimem_r", "semiten_r", "bifemlh_r"}
    assert "tfl_r" in merged.pam(28).human_muscles
    for p in merged.pams:                     # routes, sizes and coordinates are the seed's
        s = seed.pam(p.id)
        assert (p.points, p.primary_coordinate, p.diameter_mm) == (s.points, s.primary_coordinate, s.diameter_mm)
    assert {4, 7, 14, 17, 21, 23, 27}.isdisjoint(p.id for p in merged.pams)


def test_merged_seed_file_is_up_to_date():
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "make_merged_seed.py"), "--check"],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
