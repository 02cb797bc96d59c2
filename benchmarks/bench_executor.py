"""The executor: study throughput on 1 against 2 workers, local pool against Ray, per-task overhead.

``python benchmarks/bench_executor.py [--quick] [--json FILE] [--address ADDR] [--no-ray]``

1. CPU-bound study: ``n_tasks`` tasks that each burn ``cpu_s`` seconds of *process CPU time*
   (:func:`optimizers.common.probe_tasks.spin`), through :func:`~optimizers.common.executor.
   run_tasks` with a result store (what a study does), on the local pool with 1 and with 2
   workers, and on Ray with 2 CPUs. Reported: wall time, tasks/s, and the speed-up
   ``wall(1 worker) / wall(2 workers)`` (target >= 1.8) and ``wall(local 2) / wall(Ray 2)``.
   Every executor is started and warmed up (ASAGA's kernels loaded in each worker) before any
   clock runs; the configurations are then timed in turn, ``--repeats`` times, and the ratios
   are medians of the per-repeat ratios (a change of the machine's load between repeats hits
   all configurations alike).
2. A real study: ASAGA runs on the [000] landing (``optimizers.study.run_one``, no
   certification), 1 against 2 local workers and Ray.
3. Per-task overhead: ``n_noop`` no-op tasks (:func:`~optimizers.common.probe_tasks.noop`)
   through ``run_tasks`` without a store; overhead = wall / n_noop (target on Ray < 5 ms), for
   the local pool and Ray, beside the in-process cost of the same loop.

Ray: a private local instance with 2 CPUs (``--address local``, default) or the cluster at
``--address``. The machine may be shared: times are as measured; ratios come from the same run.
CPU-time tasks keep the work per task fixed when the cores are shared, but other processes
still leave the two workers less than two cores, which lowers the 1→2 speed-up.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

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


def bench(quick: bool, address: str | None, use_ray: bool, repeats: int) -> dict:
    n_tasks, cpu_s = (8, 0.25) if quick else (12, 0.5)
    n_asaga, n_gen = (4, 40) if quick else (8, 100)
    n_noop = 300 if quick else 2000
    tmp = tempfile.mkdtemp(prefix="bench_executor_")
    makers = [("local, 1 worker", lambda: LocalExecutor(1)),
              ("local, 2 workers", lambda: LocalExecutor(2))]
    if use_ray:
        addr = address or "local"
        makers.append(("Ray, 2 CPUs", lambda: RayExecutor(addr, num_cpus=2)
                       if addr == "local" else RayExecutor(addr)))
    t0 = time.perf_counter()
    run_tasks([Task(TaskKey("noop-inproc", 0, i), pt.noop, (i,)) for i in range(n_noop)])
    inproc_ms = 1e3 * (time.perf_counter() - t0) / n_noop
    executors, startup = {}, {}
    try:
        for name, make in makers:  # all started and warm before any clock runs
            t_start = time.perf_counter()
            ex = make()
            _warm(ex, ex.n_workers)
            executors[name], startup[name] = ex, time.perf_counter() - t_start
        walls = {name: {"spin": [], "asaga": [], "noop": []} for name in executors}
        # the configurations are timed in turn within each repeat, so a change of the machine's
        # load between repeats affects all of them alike; ratios are per repeat, then medians
        for rep in range(repeats):
            for name, ex in executors.items():
                tag = f"{name.split(',')[0].lower()}{ex.n_workers}-r{rep}"
                walls[name]["spin"].append(_timed(ex, _spin_tasks(n_tasks, cpu_s, tag),
                                                  f"{tmp}/{tag}-spin"))
                walls[name]["asaga"].append(_timed(ex, _asaga_tasks(n_asaga, n_gen, tag),
                                                   f"{tmp}/{tag}-asaga"))
                t0 = time.perf_counter()
                run_tasks([Task(TaskKey(f"noop-{tag}", 0, i), pt.noop, (i,))
                           for i in range(n_noop)], ex)
                walls[name]["noop"].append(time.perf_counter() - t0)
                print(f"  repeat {rep + 1}/{repeats}, {name}: CPU study "
                      f"{walls[name]['spin'][-1]:.2f} s, ASAGA study "
                      f"{walls[name]['asaga'][-1]:.2f} s, "
                      f"{1e3 * walls[name]['noop'][-1] / n_noop:.2f} ms/no-op task", flush=True)
    finally:
        for ex in executors.values():
            ex.close()
    med = lambda v: float(np.median(v))  # noqa: E731
    rows = {}
    for name, w in walls.items():
        rows[name] = {"n_workers": executors[name].n_workers, "startup_s": startup[name],
                      "spin_wall_s": med(w["spin"]), "spin_tasks_per_s": n_tasks / med(w["spin"]),
                      "asaga_wall_s": med(w["asaga"]),
                      "asaga_runs_per_min": 60 * n_asaga / med(w["asaga"]),
                      "overhead_ms_per_task": 1e3 * med(w["noop"]) / n_noop, "walls": w}
    one, two = walls["local, 1 worker"], walls["local, 2 workers"]
    ratio = lambda a, b, k: med(np.array(a[k]) / np.array(b[k]))  # noqa: E731
    ratios = {"speedup_spin_2_vs_1": ratio(one, two, "spin"),
              "speedup_asaga_2_vs_1": ratio(one, two, "asaga")}
    if "Ray, 2 CPUs" in walls:
        ray = walls["Ray, 2 CPUs"]
        ratios.update(ray_vs_local_spin=ratio(two, ray, "spin"),
                      ray_vs_local_asaga=ratio(two, ray, "asaga"))
    return {"settings": {"quick": quick, "repeats": repeats, "n_spin_tasks": n_tasks,
                         "cpu_s_per_spin_task": cpu_s, "n_asaga_runs": n_asaga,
                         "asaga_generations": n_gen, "n_noop_tasks": n_noop,
                         "address": address or "local", "cpu_count": os.cpu_count(),
                         "loadavg_at_start": os.getloadavg()},
            "rows": rows, "ratios": ratios, "in_process_ms_per_task": inproc_ms}


def table(res: dict) -> str:
    s = res["settings"]
    lines = [f"CPU-bound study: {s['n_spin_tasks']} tasks × {s['cpu_s_per_spin_task']} s CPU; "
             f"ASAGA study: {s['n_asaga_runs']} runs × {s['asaga_generations']} generations; "
             f"overhead: {s['n_noop_tasks']} no-op tasks; medians of {s['repeats']} repeats; "
             f"load average at start "
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
    ap.add_argument("--repeats", type=int, default=None,
                    help="interleaved repeats (default 3; quick 2)")
    args = ap.parse_args(argv)
    use_ray = not args.no_ray
    if use_ray:
        try:
            import ray  # noqa: F401
        except ImportError:
            print("Ray is not installed (pip install -e '.[ray]'); local pool only",
                  file=sys.stderr)
            use_ray = False
    repeats = args.repeats or (2 if args.quick else 3)
    res = bench(args.quick, args.address, use_ray, repeats)
    print()
    print(table(res))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(res, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
