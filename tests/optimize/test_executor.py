"""Where the optimiser's solves run, and runs that survive: the same design from local worker processes and
from a real local Dask cluster (several worker processes), and a run killed mid-way that resumes from its run
folder to the design of an uninterrupted run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from pamkin.optimize.config import RunConfig
from pamkin.optimize.context import RunContext
from pamkin.optimize.executor import LocalExecutor, map_tasks
from pamkin.optimize.store import RunStore, task_key

#: A quick real run: one actuator (biceps femoris short head) through every default stage.
ACTUATORS = "10"


def _square(ctx, task):
    return task * task + ctx.cfg.seed


def _design(run_dir: Path) -> dict:
    """A run's design without the parts that name its folder."""
    d = yaml.safe_load((run_dir / "design.yaml").read_text())
    d.pop("name", None)
    d.pop("description", None)
    return d


def _optimize(args: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pamkin", "optimize", "--no-audit", *args],
                          capture_output=True, text=True, **kw)


@pytest.fixture(scope="module")
def local_run(tmp_path_factory) -> Path:
    """The reference: the run on local worker processes, uninterrupted."""
    out = tmp_path_factory.mktemp("local") / "run"
    p = _optimize(["--actuators", ACTUATORS, "--out", str(out)], timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    return out


def test_map_tasks_stores_each_result_and_a_resumed_map_solves_only_the_rest(tmp_path):
    store = RunStore(tmp_path)
    ctx = RunContext(RunConfig().replace({"workers": 2, "seed": 1}), None, None, None, store=store)
    assert sorted(map_tasks(ctx, _square, [1, 2, 3], "stage")) == [2, 5, 10]
    assert store.stored() == 3
    # the same stage call again (a resumed run): every task from the store, none solved
    resumed = RunContext(RunConfig().replace({"workers": 2, "seed": 1}), None, None, None, store=RunStore(tmp_path))
    calls = []

    def counted(c, t):
        calls.append(t)
        return _square(c, t)

    resumed.cfg.workers = 1
    assert sorted(map_tasks(resumed, counted, [1, 2, 3, 4], "stage")) == [2, 5, 10, 17]
    assert calls == [4]
    assert task_key((1, (20, 2))) == task_key((1, (20, 2))) != task_key((1, (20, 3)))


def test_a_stage_whose_every_task_is_stored_resumes_with_several_workers(tmp_path):
    """A run killed after a stage's last task was stored: the resumed stage call takes every result from the
    store and starts no worker (with 2 workers this raised "max_workers must be greater than 0")."""
    ctx = RunContext(RunConfig().replace({"workers": 2, "seed": 1}), None, None, None, store=RunStore(tmp_path))
    assert sorted(map_tasks(ctx, _square, [1, 2, 3], "stage")) == [2, 5, 10]
    resumed = RunContext(RunConfig().replace({"workers": 2, "seed": 1}), None, None, None,
                         store=RunStore(tmp_path))

    def never(c, t):
        raise AssertionError("a stored task was solved again")

    assert sorted(map_tasks(resumed, never, [1, 2, 3], "stage")) == [2, 5, 10]
    assert list(LocalExecutor(2).map_unordered(never, resumed, [])) == []


def test_local_executor_runs_tasks_in_worker_processes():
    ctx = RunContext(RunConfig().replace({"workers": 2}), None, None, None)
    out = dict(LocalExecutor(2).map_unordered(_pid, ctx, list(range(4))))
    assert sorted(out) == [0, 1, 2, 3] and os.getpid() not in out.values()


def _pid(ctx, task):
    return os.getpid()


@pytest.mark.slow
def test_dask_cluster_gives_the_local_design(local_run, tmp_path):
    """The same run on a real local Dask cluster (two worker processes, one thread each) writes the same
    design as on local worker processes."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        out = tmp_path / "dask"
        p = _optimize(["--actuators", ACTUATORS, "--out", str(out), "--scheduler", cl.scheduler_address],
                      timeout=600)
        assert p.returncode == 0, p.stderr[-2000:]
        assert len(cl.workers) == 2
    assert _design(out) == _design(local_run)
    assert RunStore(out).stored() >= 2          # first fit and bone rounds, stored as they finished


@pytest.mark.slow
def test_a_killed_run_resumes_to_the_design_of_an_uninterrupted_one(local_run, tmp_path):
    """Kill a run as soon as its first task is stored; ``--resume`` reads that task back (not solved again)
    and ends with the uninterrupted run's design."""
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "pamkin", "optimize", "--no-audit", "--actuators", ACTUATORS,
                             "--workers", "1", "--out", str(out)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 600
        while RunStore(out).stored() < 1:
            assert proc.poll() is None, "the run ended before it could be killed"
            assert time.monotonic() < deadline
            time.sleep(0.2)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert not (out / "design.yaml").exists()
    again = _optimize(["--out", str(out)], timeout=60)              # no overwriting of a run folder
    assert again.returncode == 2 and "--resume" in again.stderr
    p = _optimize(["--resume", str(out)], timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "resuming" in p.stderr and "resumed)" in p.stderr
    assert _design(out) == _design(local_run)
