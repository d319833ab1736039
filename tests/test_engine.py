"""Where the work runs does not change what it computes: serial, local threads and processes,
Dask."""

from __future__ import annotations

import functools
import json
import threading

import engine_tasks
import numpy as np
import pytest

from backhoe import default_family
from backhoe.families.batched import TASK_MEMBERS
from backhoe.families.sweeps import frequency_damping_sweep
from bdft import main
from robust import engine
from robust.engine import (
    SCHEDULER_ENV,
    jobs_available,
    map_tasks,
    nested_jobs,
    scheduler_address,
)
from robust.errors import BDFTError, ParameterError
from uncertainty import margins, sample, validate_family
from uncertainty.margins import robust_margin

distributed = pytest.importorskip("distributed")
dask = pytest.importorskip("dask")


# the clusters' periodic work that no test uses, slowed or off: the workers' statistical
# profiler (every 10 ms), the event loops' tick (20 ms) and the system monitor (0.5 s) cost
# a tenth of a core per idle cluster, for the minutes the module runs
QUIET = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
}


@pytest.fixture(scope="module")
def cluster():
    with (
        dask.config.set(QUIET),
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as c,
    ):
        yield c


def test_map_tasks_keeps_the_order_on_every_engine(cluster):
    fn = functools.partial(engine_tasks.power, 3)
    args = [0.5 * i for i in range(9)]
    want = [fn(a) for a in args]
    seen = []
    assert map_tasks(fn, args, progress=seen.append) == want
    assert seen == list(range(9))
    assert map_tasks(fn, args, jobs=2) == want
    seen = []
    assert map_tasks(fn, args, scheduler=cluster.scheduler_address, progress=seen.append) == want
    assert sorted(seen) == list(range(9))
    with pytest.raises(ParameterError, match="jobs must be a positive integer"):
        map_tasks(fn, args, jobs=0)


def test_the_scheduler_comes_from_the_option_or_the_environment(monkeypatch):
    monkeypatch.delenv(SCHEDULER_ENV, raising=False)
    assert scheduler_address(None) is None
    monkeypatch.setenv(SCHEDULER_ENV, "tcp://10.0.0.1:8786")
    assert scheduler_address(None) == "tcp://10.0.0.1:8786"
    assert scheduler_address("tcp://h:1") == "tcp://h:1"


def test_an_unreachable_scheduler_is_named(monkeypatch):
    monkeypatch.setattr(engine, "CONNECT_TIMEOUT_S", 1.0)
    with pytest.raises(BDFTError, match="cannot connect to the Dask scheduler"):
        map_tasks(abs, [1, 2], scheduler="tcp://127.0.0.1:9")


def test_validation_is_the_same_bits_on_every_engine(cluster):
    fam = default_family("physical")
    # two tasks: a full one and the rest
    members = sample(fam.parameters, TASK_MEMBERS + 1234, method="mc", seed=7)
    serial = validate_family(fam, members)
    local = validate_family(fam, members, jobs=2)
    dask = validate_family(fam, members, scheduler=cluster.scheduler_address)
    for res in (local, dask):
        assert res.to_json() == serial.to_json()
        assert np.array_equal(res.max_real, serial.max_real)
        assert np.array_equal(res.member_min_damping, serial.member_min_damping)
    # a real answer: the open loop is unstable for most of the family
    assert 0.02 < serial.fraction_stable < 0.5


def test_validate_command_prints_the_same_json_with_a_scheduler(cluster, capsys):
    args = ["validate", "--samples", str(TASK_MEMBERS + 10), "--seed", "3", "--json"]
    assert main(args + ["--jobs", "1"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert main(args + ["--scheduler", cluster.scheduler_address]) == 0
    assert json.loads(capsys.readouterr().out) == plain
    assert plain["samples"] == TASK_MEMBERS + 10


def test_limit_map_is_the_same_on_a_dask_cluster(cluster, tmp_path, capsys):
    outs = []
    for extra in (["--jobs", "1"], ["--scheduler", cluster.scheduler_address]):
        argv = ["limit", "--samples", "2", "--sets", "force/handle", "--basis-check", "1"]
        argv += [*extra, "--out", str(tmp_path / f"l{len(outs)}"), "--json"]
        assert main(argv) == 0
        obj = json.loads(capsys.readouterr().out)
        obj.pop("report")
        outs.append(json.dumps(obj, sort_keys=True))
    assert outs[0] == outs[1]
    obj = json.loads(outs[0])
    assert obj["sets"][0]["samples"] == 2 and len(obj["critical"]) == 2


def test_a_local_dask_cluster_on_request():
    fn = functools.partial(engine_tasks.power, 2)
    with dask.config.set(QUIET):
        assert map_tasks(fn, [1.0, 2.0, 3.0], scheduler="local:2") == [fn(x) for x in (1, 2, 3)]
    with pytest.raises(ParameterError, match="local:N"):
        map_tasks(fn, [1.0], scheduler="local:zero")


def test_sweeps_are_the_same_bits_on_every_engine(cluster, tmp_path, capsys):
    fam = default_family("physical").with_workspace_factor(2.0)
    # 3 x 3 grid points of 6,000 members: 54,000 in all, above the size that starts processes
    kw = dict(pair="arm", n_f=3, n_z=3, members=6000, seed=4)
    seen = []
    serial = frequency_damping_sweep(fam, **kw, progress=seen.append)
    assert sum(seen) == 9 * 6001
    local = frequency_damping_sweep(fam, **kw, jobs=2)
    seen = []
    dask = frequency_damping_sweep(
        fam, **kw, scheduler=cluster.scheduler_address, progress=seen.append
    )
    assert seen == [6001] * 9
    for res in (local, dask):
        assert res.settings == serial.settings
        for k, col in serial.columns.items():
            assert np.array_equal(res.columns[k], col), k
    # a real map: the arm's frequency and damping move the fraction stable
    frac = serial.columns["fraction_stable"]
    assert frac.max() - frac.min() > 0.05
    # the command: the same JSON table with a scheduler as in one process
    outs = []
    for extra in (["--jobs", "1"], ["--scheduler", cluster.scheduler_address]):
        argv = ["sweep", "structure-frequency", "--samples", "50", "--points", "3", *extra]
        assert main([*argv, "--out", str(tmp_path / f"s{len(outs)}"), "--json"]) == 0
        obj = json.loads(capsys.readouterr().out)
        obj.pop("report")
        outs.append(json.dumps(obj, sort_keys=True))
    assert outs[0] == outs[1]


@pytest.mark.slow
def test_margin_is_the_same_on_every_engine(cluster, monkeypatch):
    # the lower bound's sub-boxes certified in one process, two local processes and on the
    # cluster: the same bounds and the same statistics of every scale tried. The upper
    # bound's search runs in this process whatever the engine (it takes no engine option):
    # searched once, its result is given to the other two calls (two thirds of the time)
    search, found = margins.margin_upper_bound, {}

    def search_once(loop, **kw):
        key = repr(sorted(kw.items()))
        if key not in found:
            found[key] = search(loop, **kw)
        return found[key]

    monkeypatch.setattr(margins, "margin_upper_bound", search_once)
    fam = default_family("physical")
    # the eigenvalue route (the one whose sub-boxes go to the engines)
    kw = dict(samples=200, max_boxes=24, ladder=6, iterations=2, method="eigenvalues")
    outs = []
    for engine_kw in ({}, {"jobs": 2}, {"scheduler": cluster.scheduler_address}):
        res = robust_margin(fam, **kw, **engine_kw)
        obj = res.to_json()
        obj.pop("timings_s", None)
        outs.append(json.dumps(obj, sort_keys=True))
    assert outs[0] == outs[1] == outs[2]
    assert len(found) == 1  # the three calls asked the search the same question
    obj = json.loads(outs[0])
    # a real answer: a positive certified scale below the upper bound, and the last scale
    # tried needed several waves of sub-boxes
    assert 0 < obj["lower"] < obj["upper"] < 0.2
    assert max(h["boxes"] for h in obj["certificate"]["history"]) > 8


def test_nested_jobs_grant_and_refuse():
    assert jobs_available() == 1
    with nested_jobs(3):
        assert jobs_available() == 3
        with nested_jobs(1):
            assert jobs_available() == 1
        assert jobs_available() == 3
    assert jobs_available() == 1
    for bad in (0, -2, 1.5, True, "2"):
        with pytest.raises(ParameterError, match="nested_jobs: jobs"):
            with nested_jobs(bad):
                pass


def test_idle_worker_processes_are_ended_on_request():
    import os

    first = set(map_tasks(engine_tasks.pid, range(6), jobs=2))
    assert os.getpid() not in first and 1 <= len(first) <= 2
    assert engine.stop_workers() is True
    for pid in first:  # ended: the process is gone (or a reaped zombie no longer ours)
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
    assert engine.stop_workers() is False  # nothing left to end
    # the next call starts new workers
    again = set(map_tasks(engine_tasks.pid, range(6), jobs=2))
    assert again and not (again & first)
    assert engine.stop_workers() is True


def _meet(barrier, x):
    # passes only if another task runs at the same time (two threads side by side)
    barrier.wait(timeout=30)
    return x * x, threading.current_thread().name


def test_threads_run_side_by_side_in_this_process_and_keep_the_order():
    barrier = threading.Barrier(2)
    seen = []
    out = map_tasks(
        functools.partial(_meet, barrier), range(6), jobs=2, threads=True, progress=seen.append
    )
    assert [r[0] for r in out] == [x * x for x in range(6)]
    assert {r[1] for r in out} <= {"bdft-task_0", "bdft-task_1"}
    assert sorted(seen) == list(range(6))


def _fail_at(k, x):
    if x == k:
        raise ValueError(f"task {x} failed")
    return x


def test_a_failing_thread_task_raises_its_own_error():
    with pytest.raises(ValueError, match="task 3 failed"):
        map_tasks(functools.partial(_fail_at, 3), range(40), jobs=2, threads=True)
