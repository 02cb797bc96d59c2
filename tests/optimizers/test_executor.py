"""The executor: keyed tasks, streaming atomic results, resume, faults; local pool and real Ray."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from optimizers.common import probe_tasks as pt
from optimizers.common.executor import (
    LocalExecutor,
    ResultStore,
    Task,
    TaskKey,
    get_executor,
    run_tasks,
)


def _tasks(fn, directory, n, cpu_s=0.0, problem="probe"):
    return [Task(TaskKey(problem, 7, i), fn, (str(directory), i, cpu_s)) for i in range(n)]


def _done_counts(directory) -> Counter:
    return Counter(int(p.name.split("_")[1]) for p in Path(directory).glob("done_*"))


# ----------------------------------------------------------------------------- contracts


def test_task_refuses_closures_and_lambdas():
    def local(x):
        return x

    with pytest.raises(TypeError, match="closure"):
        Task(TaskKey("p", 0, 0), local)
    with pytest.raises(TypeError, match="lambda"):
        Task(TaskKey("p", 0, 0), lambda: 1)
    Task(TaskKey("p", 0, 0), pt.noop)  # a module-level function is accepted


def test_task_key_validation_and_filename():
    with pytest.raises(ValueError, match="seed"):
        TaskKey("p", -1, 0)
    with pytest.raises(ValueError, match="problem"):
        TaskKey("", 0, 0)
    assert TaskKey("zhu 2007/x", 3, 12).filename == "zhu_2007_x__seed3__000012"
    with pytest.raises(ValueError, match="n_workers"):
        LocalExecutor(-1)


def test_duplicate_keys_refused():
    t = Task(TaskKey("p", 0, 0), pt.noop)
    with pytest.raises(ValueError, match="unique"):
        run_tasks([t, t])


def test_store_identity_refuses_other_study(tmp_path):
    ResultStore(tmp_path, {"algorithm": "ASAGA", "n": 1})
    with pytest.raises(ValueError, match="algorithm"):
        ResultStore(tmp_path, {"algorithm": "GA", "n": 1})


def test_npz_store_round_trip_and_resume(tmp_path):
    """fmt="npz": dicts of arrays, compressed, read back without pickle; run_tasks skips them."""
    store = ResultStore(tmp_path, {"study": "npz"}, fmt="npz")
    key = TaskKey("p", 0, 3)
    value = {"x": np.arange(6.0).reshape(2, 3), "ok": np.array([True, False]),
             "t": np.array(1.5)}
    path = store.put(key, value)
    assert path.name == key.filename + ".npz" and key in store
    got = store.get(key)
    assert set(got) == set(value)
    for k in value:
        np.testing.assert_array_equal(got[k], value[k])
        assert got[k].dtype == value[k].dtype
    assert store.keys() == [key.filename]
    res, rep = run_tasks([Task(key, pt.noop, (1,))], LocalExecutor(0), store)
    assert (rep.n_skipped, rep.n_done) == (1, 0) and set(res[key]) == set(value)
    with pytest.raises(TypeError, match="dicts of arrays"):
        store.put(TaskKey("p", 0, 4), [1, 2])
    with pytest.raises(ValueError, match="npz"):  # object arrays are refused on read
        np.savez(store.path(TaskKey("p", 0, 5)), o=np.array([{}], dtype=object))
        store.get(TaskKey("p", 0, 5))
    with pytest.raises(ValueError, match="fmt"):
        ResultStore(tmp_path / "other", fmt="csv")


@pytest.mark.parametrize("fmt, value", [("npz", {"x": np.arange(50.0)}),
                                        ("json", {"x": list(range(50))}),
                                        ("pickle", {"x": list(range(50))})])
def test_damaged_entry_is_named_moved_aside_and_run_again(tmp_path, capsys, fmt, value):
    store = ResultStore(tmp_path, {"study": "damage"}, fmt=fmt)
    key = TaskKey("p", 0, 1)
    path = store.put(key, value)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])  # truncated
    with pytest.raises(ValueError, match=f"stored result {path} is damaged"):
        store.get(key)
    assert path.exists()  # get never moves anything
    # membership moves it aside with a message, so the task runs again
    assert key not in store
    assert f"stored result {path} is damaged" in capsys.readouterr().out
    damaged = path.with_name(path.name + ".damaged")
    assert damaged.exists() and not path.exists() and not store.readable(key)
    store.put(key, value)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    res, rep = run_tasks([Task(key, pt.noop, (value,))], LocalExecutor(0), store)
    assert (rep.n_skipped, rep.n_done) == (0, 1)  # run again, not read back
    assert "is damaged" in capsys.readouterr().out
    np.testing.assert_array_equal(store.get(key)["x"], value["x"])


def test_store_validate_marks_incomplete_entries_damaged(tmp_path, capsys):
    def need_y(v):
        if "y" not in v:
            raise ValueError("lacks ['y']")

    store = ResultStore(tmp_path, fmt="npz", validate=need_y)
    key = TaskKey("p", 0, 0)
    store.put(key, {"x": np.zeros(2)})
    with pytest.raises(ValueError, match=r"is damaged \(ValueError: lacks \['y'\]\)"):
        store.get(key)
    assert not store.readable(key) and store.path(key).with_suffix(".npz.damaged").exists()
    store.put(key, {"x": np.zeros(2), "y": np.ones(1)})
    assert key in store


@pytest.fixture
def fake_ray(monkeypatch):
    """Ray's entry points replaced: ``ray.init`` records its arguments and reports a cluster of
    3 CPUs; no instance is started or contacted. Yields the list of ``ray.init`` calls."""
    import ray

    calls = []
    state = {"up": False}

    def init(address=None, **kw):
        calls.append({"address": address, **kw})
        state["up"] = True

    def shutdown():
        state["up"] = False

    class _Remote:
        def options(self, **kw):
            return self

    monkeypatch.setattr(ray, "init", init)
    monkeypatch.setattr(ray, "shutdown", shutdown)
    monkeypatch.setattr(ray, "is_initialized", lambda: state["up"])
    monkeypatch.setattr(ray, "cluster_resources", lambda: {"CPU": 3.0})
    monkeypatch.setattr(ray, "remote", lambda fn: _Remote())
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    yield calls


def test_get_executor_without_an_address_is_the_local_pool(fake_ray):
    with get_executor(None, 2) as ex:
        assert isinstance(ex, LocalExecutor) and ex.n_workers == 2
        assert ex.describe() == "local process pool (2 workers)"
    with get_executor(None, None) as ex:  # default: every core
        assert isinstance(ex, LocalExecutor) and ex.n_workers == (os.cpu_count() or 1)
    with get_executor(None, 2, max_retries=5) as ex:
        assert ex.max_retries == 5
    assert fake_ray == []  # Ray never initialised


def test_get_executor_with_zero_workers_runs_in_process(fake_ray):
    with get_executor(None, 0) as ex:
        assert isinstance(ex, LocalExecutor) and ex.n_workers == 0
        assert ex.describe() == "in-process (no workers)"
        res, rep = run_tasks([Task(TaskKey("p", 0, 0), pt.noop, (4,))], ex)
    assert rep.n_done == 1 and fake_ray == []


def test_get_executor_from_the_ray_address_variable(fake_ray, monkeypatch):
    from optimizers.common.executor import RayExecutor

    monkeypatch.setenv("RAY_ADDRESS", "10.0.0.5:6379")
    with get_executor(None, 2) as ex:  # the variable wins over the local pool
        assert isinstance(ex, RayExecutor) and ex.address == "10.0.0.5:6379"
        assert ex.n_workers == 3 and ex.describe() == "Ray at 10.0.0.5:6379 (3 CPUs)"
    assert [c["address"] for c in fake_ray] == ["10.0.0.5:6379"]
    assert "num_cpus" not in fake_ray[0]  # a cluster's CPUs are its own
    with get_executor("auto", 2) as ex:  # an explicit address wins over the variable
        assert ex.address == "auto"
    assert fake_ray[-1]["address"] == "auto"


def test_get_executor_local_address_starts_a_private_ray(fake_ray):
    from optimizers.common.executor import RayExecutor

    with get_executor("local", 2) as ex:
        assert isinstance(ex, RayExecutor) and ex.address == "local"
    with get_executor("local", None):
        pass
    # the workers given become the private instance's CPUs
    assert [(c["address"], c.get("num_cpus")) for c in fake_ray] == [("local", 2),
                                                                      ("local", None)]


@pytest.mark.parametrize("bad", ["nonsense", "127.0.0.1", "host:port", ":6379", "host:0",
                                 "host:70000"])
def test_get_executor_refuses_a_bad_address_before_contacting_ray(fake_ray, monkeypatch, bad):
    with pytest.raises(ValueError, match=rf"--address = '{bad}' is not a Ray address: use "
                                         r"'local'.*'auto'.*'host:port' or 'ray://host:port'"):
        get_executor(bad, 2)
    monkeypatch.setenv("RAY_ADDRESS", bad)
    with pytest.raises(ValueError, match=rf"\$RAY_ADDRESS = '{bad}' is not a Ray address"):
        get_executor(None, 2)
    assert fake_ray == []


# ----------------------------------------------------------------------------- local pool


def test_in_process_stream_resume_and_exactly_once(tmp_path):
    """Results stream to the store one by one; an interrupted run resumes with only the missing
    keys; nothing is run twice."""
    marks = tmp_path / "marks"
    store = ResultStore(tmp_path / "store", {"study": "probe"})
    tasks = _tasks(pt.record, marks, 6)
    seen = []
    res, rep = run_tasks(tasks, LocalExecutor(0), store, max_tasks=4,
                         on_result=lambda t, r: seen.append(len(store.keys())))
    assert rep.n_done == 4 and seen == [1, 2, 3, 4]  # each stored before the next arrives
    res, rep = run_tasks(tasks, LocalExecutor(0), store)
    assert (rep.n_skipped, rep.n_done) == (4, 2)
    assert {k.index: v["square"] for k, v in res.items()} == {i: i * i for i in range(6)}
    assert _done_counts(marks) == Counter({i: 1 for i in range(6)})
    assert not list((tmp_path / "store" / "results").glob(".*tmp"))  # no temporary left


def test_local_pool_survives_a_killed_worker(tmp_path):
    """A worker process SIGKILLed mid-task: the pool is rebuilt, the task re-run, and every
    task's result is stored exactly once."""
    marks = tmp_path / "marks"
    store = ResultStore(tmp_path / "store")
    tasks = _tasks(pt.record, marks, 5, 0.05)
    tasks[2] = Task(TaskKey("probe", 7, 2), pt.kill_worker_once, (str(marks), 2, 0.05))
    with LocalExecutor(2) as ex:
        res, rep = run_tasks(tasks, ex, store)
        assert ex.n_pool_restarts == 1
    assert (marks / "killed_000002").exists()
    assert sorted(k.index for k in res) == list(range(5)) and rep.n_done == 5
    assert len(store.keys()) == 5
    assert _done_counts(marks)[2] == 1  # the killed task completed once, on the second try


def test_task_exception_propagates_after_storing_finished(tmp_path):
    store = ResultStore(tmp_path)
    tasks = [Task(TaskKey("p", 0, 0), pt.noop, (1,)),
             Task(TaskKey("p", 0, 1), pt.spin, ("not a number",))]
    with pytest.raises(ValueError):
        run_tasks(tasks, LocalExecutor(0), store)
    assert store.keys() == ["p__seed0__000000"]


# ----------------------------------------------------------------------------- Ray


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def ray_cluster(tmp_path, monkeypatch):
    """A real Ray head node on 127.0.0.1 (``ray start --block`` in its own session, stopped by
    signalling that session only), 2 CPUs; yields its address.

    Token authentication is off for this private test cluster, in the head and in the driver
    alike: with it on, another Ray instance started meanwhile by the same user (a study, a
    benchmark) can rewrite the shared ``~/.ray/auth_token`` and the driver is refused."""
    import ray  # noqa: F401  (the [test] extra: a missing Ray fails, not skips)

    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    ray_bin = Path(sys.executable).with_name("ray")
    port = _free_port()
    log = open(tmp_path / "ray_start.log", "w")
    proc = subprocess.Popen(
        [str(ray_bin), "start", "--head", "--node-ip-address=127.0.0.1", f"--port={port}",
         "--num-cpus=2", "--include-dashboard=false", "--disable-usage-stats", "--block"],
        stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
        env={**os.environ, "RAY_AUTH_MODE": "disabled"})
    try:
        yield f"127.0.0.1:{port}"
    finally:
        import ray

        if ray.is_initialized():
            ray.shutdown()
        # the head's processes (GCS, raylet, workers) live in the session started for it:
        # ask them to stop, then make sure (only that process group is signalled)
        for sig, wait_s in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 10.0)):
            try:
                os.killpg(proc.pid, sig)
                proc.wait(timeout=wait_s)
                break
            except ProcessLookupError:
                break
            except subprocess.TimeoutExpired:
                continue
        for pid in _session_members(proc.pid):  # workers have their own groups, same session
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        log.close()


def _session_members(sid: int) -> list[int]:
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[3]) == sid:  # field 6 of /proc/<pid>/stat: session id
                out.append(int(d.name))
    return out


def _connect(address, timeout_s=120.0):
    from optimizers.common.executor import RayExecutor

    t_end = time.monotonic() + timeout_s
    while True:
        try:
            return RayExecutor(address)
        except (ConnectionError, RuntimeError, TimeoutError):
            import ray

            if ray.is_initialized():
                ray.shutdown()
            if time.monotonic() > t_end:
                raise
            time.sleep(1.0)


def test_ray_cluster_study_with_a_killed_worker(ray_cluster, tmp_path, monkeypatch):
    """On a real local cluster reached through RAY_ADDRESS: a study of 12 tasks in which two
    workers are SIGKILLed mid-task completes with every task done exactly once and stored once;
    a rerun does nothing."""
    monkeypatch.setenv("RAY_ADDRESS", ray_cluster)
    marks = tmp_path / "marks"
    store = ResultStore(tmp_path / "store", {"study": "ray-fault"})
    tasks = _tasks(pt.record, marks, 12, 0.05)
    for i in (3, 8):
        tasks[i] = Task(TaskKey("probe", 7, i), pt.kill_worker_once, (str(marks), i, 0.1))
    ex = _connect(None)  # from RAY_ADDRESS
    try:
        assert ex.kind == "ray" and ex.n_workers == 2
        res, rep = run_tasks(tasks, ex, store)
        assert rep.n_done == 12
        assert {k.index: v["square"] for k, v in res.items()} == {i: i * i for i in range(12)}
        assert all((marks / f"killed_{i:06d}").exists() for i in (3, 8))
        assert _done_counts(marks) == Counter({i: 1 for i in range(12)})
        assert len(store.keys()) == 12
        stored = json.loads(store.path(TaskKey("probe", 7, 8)).read_text())
        assert stored["value"]["square"] == 64 and stored["store"]["key"] == ["probe", 7, 8]
        res2, rep2 = run_tasks(tasks, ex, store)  # resume: everything is there already
        assert (rep2.n_skipped, rep2.n_done) == (12, 0) and res2 == res
        # a task's own exception reaches the caller as itself (not retried)
        with pytest.raises(ValueError):
            run_tasks([Task(TaskKey("p", 0, 0), pt.spin, ("x",))], ex)
    finally:
        ex.close()


def test_solve_many_on_an_executor_matches_serial():
    """The per-case optima (agents.evaluate, agents.dataset) through the executor: chunks of the
    warm-start chain as keyed tasks give the serial chain's optima."""
    import numpy as np

    from lunar_env import get_scenario
    from optimizers.indirect.batch import solve_many

    sc = get_scenario("zhu2007")
    states = sc.sample_initial(np.random.default_rng(5), 4)
    serial = solve_many(sc, states, progress=False)
    chunked = solve_many(sc, states, progress=False, executor=LocalExecutor(0), chunk_size=2)
    for a, b in zip(serial, chunked, strict=True):
        assert a.success and b.success
        assert abs(a.fuel_kg - b.fuel_kg) < 1e-6 * a.fuel_kg


@pytest.mark.slow
def test_pinpoint_optima_on_an_executor(tmp_path):
    """The pinpoint per-case optima of agents.evaluate through the executor: chunks are keyed
    tasks, every case solved once and cached (slow: ~1.5 min of GPM solves on 2 shared cores;
    the quick version of the routing is test_solve_many_on_an_executor_matches_serial)."""
    import gymnasium as gym

    import lunar_env  # noqa: F401
    import optimizers.optimum.pinpoint as po
    from guidance.flight import initial_states

    scenario = gym.make("LunarPinpointLanding-v0").unwrapped.scenario
    states = initial_states("LunarPinpointLanding-v0", 2, 2026)
    opts = po.pinpoint_optima(scenario, states, cache_dir=tmp_path, progress=False,
                              executor=LocalExecutor(0))
    assert all(o.success for o in opts) and len(list(tmp_path.glob("*.npz"))) == 2
    np.testing.assert_allclose([o.states_nd[0] for o in opts], states, rtol=0, atol=1e-12)
