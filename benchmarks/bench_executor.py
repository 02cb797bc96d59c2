"""The executor: study throughput on 1 against 2 workers, local pool against Ray, per-task overhead.

``python benchmarks/bench_executor.py [--quick] [--json FILE] [--address ADDR] [--no-ray]``

1. CPU-bound study: ``n_tasks`` tasks that each burn ``cpu_s`` seconds of *process CPU time*
   (:func:`optimizers.common.probe_tasks.spin`), through :func:`~optimizers.common.executor.
   run_tasks` with a result store (what a study does), on the local pool with 1 and with 2
   workers, and on Ray with 2 CPUs. Reported: wall time, tasks/s, and the speed-up
   ``wall(1 worker) / wall(2 workers)`` (target >= 1.8) and ``wall(local 2) / wall(Ray 2)``.
   Workers are started before the clock starts (a warm-up task per worker).
2. A real study: ASAGA runs on the [000] landing (``optimizers.study.run_one``, no
   certification), 1 against 2 local workers and Ray.
3. Per-task overhead: ``n_noop`` no-op tasks (:func:`~optimizers.common.probe_tasks.noop`)
   through ``run_tasks`` without a store; overhead = wall / n_noop (target on Ray < 5 ms), for
   the local pool and Ray, beside the in-process cost of the same loop.

Ray: a private local instance with 2 CPUs (``--address local``, default) or the cluster at
``--address``. The machine may be shared: times are as measured; ratios come from the same run.
CPU-time tasks keep the work per task fixed under load, but a loaded machine still gives the
two workers less than two cores, which lowers the 1→2 speed-up.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

from optimizers.common import probe_tasks as pt
from optimizers.common.executor import (
    LocalExecutor,
    RayExecutor,
    ResultStore,
    Task,
    TaskKey,
    run_tasks,
)


def _warm(ex, n: int) -> None:
    """Start the workers and load the ASAGA problem (numba kernels) in each before timing."""
    from optimizers.study import run_one

    run_tasks([Task(TaskKey("warm", 0, i), run_one,
                    ("asaga", {"n_generations": 2}, "zhu2007", {}, 0, i, None))
               for i in range(2 * n)], ex)


def _timed(ex, tasks, store_dir) -> float:
    store = ResultStore(store_dir) if store_dir else None
    t0 = time.perf_counter()
    _, rep = run_tasks(tasks, ex, store)
    wall = time.perf_counter() - t0
    assert rep.n_done == len(tasks)
    return wall


def _spin_tasks(n: int, cpu_s: float, tag: str):
    return [Task(TaskKey(f"spin-{tag}", 0, i), pt.spin, (cpu_s, i)) for i in range(n)]


def _asaga_tasks(n: int, n_gen: int, tag: str):
    from optimizers.study import run_one

    return [Task(TaskKey(f"asaga-{tag}", 0, i), run_one,
                 ("asaga", {"n_generations": n_gen}, "zhu2007", {}, 0, i, None))
            for i in range(n)]


def bench(quick: bool, address: str | None, use_ray: bool) -> dict:
    n_tasks, cpu_s = (8, 0.5) if quick else (24, 1.0)
    n_asaga, n_gen = (4, 60) if quick else (12, 150)
    n_noop = 300 if quick else 2000
    rows: dict[str, dict] = {}
    tmp = tempfile.mkdtemp(prefix="bench_executor_")
    executors = [("local, 1 worker", lambda: LocalExecutor(1)),
                 ("local, 2 workers", lambda: LocalExecutor(2))]
    if use_ray:
        executors.append(("Ray, 2 CPUs", lambda: RayExecutor(address or "local", num_cpus=2)
                          if (address or "local") == "local" else RayExecutor(address)))
    # in-process reference for the overhead loop
    t0 = time.perf_counter()
    run_tasks([Task(TaskKey("noop-inproc", 0, i), pt.noop, (i,)) for i in range(n_noop)])
    inproc_ms = 1e3 * (time.perf_counter() - t0) / n_noop
    for name, make in executors:
        t_start = time.perf_counter()
        ex = make()
        try:
            _warm(ex, ex.n_workers)
            start_s = time.perf_counter() - t_start
            tag = name.split(",")[0].lower() + str(ex.n_workers)
            w_spin = _timed(ex, _spin_tasks(n_tasks, cpu_s, tag), f"{tmp}/{tag}-spin")
            w_asaga = _timed(ex, _asaga_tasks(n_asaga, n_gen, tag), f"{tmp}/{tag}-asaga")
            t0 = time.perf_counter()
            run_tasks([Task(TaskKey(f"noop-{tag}", 0, i), pt.noop, (i,))
                       for i in range(n_noop)], ex)
            w_noop = time.perf_counter() - t0
        finally:
            ex.close()
        rows[name] = {"n_workers": ex.n_workers, "startup_s": start_s,
                      "spin_wall_s": w_spin, "spin_tasks_per_s": n_tasks / w_spin,
                      "asaga_wall_s": w_asaga, "asaga_runs_per_min": 60 * n_asaga / w_asaga,
                      "overhead_ms_per_task": 1e3 * w_noop / n_noop}
        print(f"  {name}: start {start_s:.1f} s, spin study {w_spin:.2f} s, ASAGA study "
              f"{w_asaga:.2f} s, {1e3 * w_noop / n_noop:.2f} ms/no-op task", flush=True)
    one, two = rows["local, 1 worker"], rows["local, 2 workers"]
    ratios = {"speedup_spin_2_vs_1": one["spin_wall_s"] / two["spin_wall_s"],
              "speedup_asaga_2_vs_1": one["asaga_wall_s"] / two["asaga_wall_s"]}
    if "Ray, 2 CPUs" in rows:
        ray = rows["Ray, 2 CPUs"]
        ratios.update(ray_vs_local_spin=two["spin_wall_s"] / ray["spin_wall_s"],
                      ray_vs_local_asaga=two["asaga_wall_s"] / ray["asaga_wall_s"])
    return {"settings": {"quick": quick, "n_spin_tasks": n_tasks, "cpu_s_per_spin_task": cpu_s,
                         "n_asaga_runs": n_asaga, "asaga_generations": n_gen,
                         "n_noop_tasks": n_noop, "address": address or "local",
                         "cpu_count": os.cpu_count(), "loadavg_at_start": os.getloadavg()},
            "rows": rows, "ratios": ratios, "in_process_ms_per_task": inproc_ms}


def table(res: dict) -> str:
    s = res["settings"]
    lines = [f"CPU-bound study: {s['n_spin_tasks']} tasks × {s['cpu_s_per_spin_task']} s CPU; "
             f"ASAGA study: {s['n_asaga_runs']} runs × {s['asaga_generations']} generations; "
             f"overhead: {s['n_noop_tasks']} no-op tasks; load average at start "
             f"{s['loadavg_at_start'][0]:.1f} on {s['cpu_count']} cores",
             "",
             "| executor | start (s) | CPU study wall (s) | tasks/s | ASAGA study wall (s) | "
             "runs/min | overhead (ms/task) |",
             "|---|---|---|---|---|---|---|"]
    for name, r in res["rows"].items():
        lines.append(f"| {name} | {r['startup_s']:.1f} | {r['spin_wall_s']:.2f} | "
                     f"{r['spin_tasks_per_s']:.2f} | {r['asaga_wall_s']:.2f} | "
                     f"{r['asaga_runs_per_min']:.1f} | {r['overhead_ms_per_task']:.2f} |")
    r = res["ratios"]
    lines += ["", f"speed-up 2 vs 1 local workers: CPU study {r['speedup_spin_2_vs_1']:.2f}×, "
              f"ASAGA study {r['speedup_asaga_2_vs_1']:.2f}× (target >= 1.8)"]
    if "ray_vs_local_spin" in r:
        lines.append(f"Ray (2 CPUs) against the local pool (2 workers): CPU study "
                     f"{r['ray_vs_local_spin']:.2f}×, ASAGA study {r['ray_vs_local_asaga']:.2f}× "
                     "(> 1: Ray faster)")
    lines.append(f"in-process loop: {res['in_process_ms_per_task']:.3f} ms/task")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer, shorter tasks (~1 min)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--address", default=None,
                    help="Ray cluster (default: a private local instance with 2 CPUs)")
    ap.add_argument("--no-ray", action="store_true", help="local pool only")
    args = ap.parse_args(argv)
    use_ray = not args.no_ray
    if use_ray:
        try:
            import ray  # noqa: F401
        except ImportError:
            print("Ray is not installed (pip install -e '.[ray]'); local pool only",
                  file=sys.stderr)
            use_ray = False
    res = bench(args.quick, args.address, use_ray)
    print()
    print(table(res))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(res, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
