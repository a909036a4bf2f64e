"""The output layer (pamkin.outputs) and the commands' output paths: nothing a user has is lost — pipes and
symbolic links are written through, a failed write leaves the old file, a multi-file output appears complete or
not at all, existing run / report / audit folders are refused before any work unless --force."""

from __future__ import annotations

import os
import threading

import pytest

from pamkin.cli import main
from pamkin.errors import OutputError
from pamkin.outputs import check_output_folder, output_folder, write_file


def _leftovers(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_a_fifo_is_written_through_and_stays_a_fifo(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    write_file(fifo, "through the pipe")
    reader.join(10)
    assert got == [b"through the pipe"] and fifo.is_fifo() and _leftovers(tmp_path) == []


def test_a_symlink_is_written_through_and_stays_a_link(tmp_path):
    target = tmp_path / "real.yaml"
    target.write_text("old")
    link = tmp_path / "link.yaml"
    link.symlink_to(target)
    assert write_file(link, "new") == target
    assert link.is_symlink() and target.read_text() == "new" and _leftovers(tmp_path) == []


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary_file(tmp_path, monkeypatch):
    f = tmp_path / "design.yaml"
    f.write_text("the user's design")

    def broken(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken)
    with pytest.raises(OSError, match="disk full"):
        write_file(f, "half a design")
    assert f.read_text() == "the user's design" and _leftovers(tmp_path) == []


def test_a_folder_is_not_a_file(tmp_path):
    with pytest.raises(OutputError, match="is a folder"):
        write_file(tmp_path, "x")
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match="is not a folder"):
        write_file(tmp_path / "file" / "below.txt", "y")


def test_an_interrupted_multi_file_output_leaves_the_old_one_whole(tmp_path):
    out = tmp_path / "report"
    out.mkdir()
    (out / "index.html").write_text("old index")
    (out / "pam01.png").write_text("old figure")
    with pytest.raises(OutputError, match="holds files already"):
        check_output_folder(out)
    with pytest.raises(KeyboardInterrupt), output_folder(out, force=True) as tmp:
        (tmp / "index.html").write_text("new index")
        raise KeyboardInterrupt
    assert sorted(p.name for p in out.iterdir()) == ["index.html", "pam01.png"]
    assert (out / "index.html").read_text() == "old index" and _leftovers(tmp_path) == []
    with output_folder(out, force=True) as tmp:            # --force: replaced whole, no stale figure
        (tmp / "index.html").write_text("new index")
    assert sorted(p.name for p in out.iterdir()) == ["index.html"] and _leftovers(tmp_path) == []


def _no_work(*a, **k):
    raise AssertionError("the work started before the output path was checked")


def test_view_onto_a_folder_fails_before_any_work_and_writes_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("pamkin.viz.meshcat_view.build_view", _no_work)
    assert main(["view", "--html", str(tmp_path), "--no-meshes"]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path}: is a folder" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_optimize_refuses_a_run_folder_before_any_work(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    (run / "design.yaml").write_text("a 9-minute run's design")
    assert main(["optimize", "--out", str(run), "--no-audit", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "holds a run already (design.yaml)" in err and "--force" in err and "--resume" in err
    assert (run / "design.yaml").read_text() == "a 9-minute run's design" and sorted(os.listdir(run)) == ["design.yaml"]


def test_audit_refuses_an_existing_output_folder_before_the_audit(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("pamkin.audit.measure.audit_design", _no_work)
    out = tmp_path / "audit"
    out.mkdir()
    (out / "scorecard.txt").write_text("another design's scorecard")
    assert main(["audit", "thesis", "--quick", "--out", str(out)]) == 2
    assert "holds files already" in capsys.readouterr().err
    assert (out / "scorecard.txt").read_text() == "another design's scorecard"
