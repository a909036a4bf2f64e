"""Bounded requests (every size option has a range; a grid that cannot fit in memory is refused up front with
its estimate), strict JSON (null for undefined numbers) and exit codes that mean one thing each: 0 success,
1 an audit limit failed (also when the reader closes the pipe early), 2 bad input, 3 infeasible."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from pamkin.cli import main
from pamkin.cli.bounds import check_memory
from pamkin.errors import ParameterError
from pamkin.outputs import strict_json


def _no_work(*a, **k):
    raise AssertionError("the computation started before the request was checked")


@pytest.mark.parametrize("argv,message", [
    (["torques", "--coords", "hip_flexion,knee_angle,ankle_angle,hip_adduction", "-n", "60"], "GiB needed"),
    (["torques", "-n", "1"], "-n must be an integer in [2, 201], got 1"),
    (["view", "--html", "v.html", "--no-meshes", "--sweep", "knee_angle_r", "-n", "100000"],
     "-n must be an integer in [2, 1001], got 100000"),
    (["compare", "-n", "5000"], "-n must be an integer in [2, 1001]"),
    (["report", "--n1", "0", "--out", "r"], "--n1 must be an integer in [2, 10001]"),
    (["audit", "--random", "0"], "--random must be an integer in [1, 100000]"),
])
def test_oversized_requests_are_refused_up_front(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("pamkin.human.model.Model.capacity", _no_work)     # refused before any computation
    monkeypatch.setattr("pamkin.viz.meshcat_view.build_view", _no_work)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_the_memory_estimate_names_the_request(monkeypatch):
    monkeypatch.setattr("pamkin.cli.bounds.available_memory", lambda: 4 << 30)      # a 8 GiB machine
    with pytest.raises(ParameterError, match=r"the grid: about 8\.0 GiB needed \(1073741824 items\), more than "
                                             r"the 4\.0 GiB"):
        check_memory("the grid", 2**30, 8)
    check_memory("a small grid", 1000, 8)


def test_json_output_is_strict():
    text = strict_json({"nan": float("nan"), "inf": [float("inf"), 1.5], "arr": np.array([0.5, np.nan]),
                        "int": np.int64(3)})
    assert json.loads(text) == {"nan": None, "inf": [None, 1.5], "arr": [0.5, None], "int": 3}
    assert "NaN" not in text and "Infinity" not in text


def test_a_failing_audit_exits_1_even_when_the_reader_stops_early():
    """`pamkin audit --json | head` of a failing design (the thesis design fails limits) exits 1, not 0."""
    p = subprocess.Popen([sys.executable, "-m", "pamkin", "audit", "thesis", "--quick", "--json", "--random", "40",
                          "--ik", "none", "--no-gait-plan"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first = p.stdout.read(5)
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait(timeout=600) == 1, err[-2000:]
    assert first == b'{\n "d' and "Traceback" not in err
