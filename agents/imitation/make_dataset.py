"""Command line of the optimal-landing datasets: ``python -m agents.imitation.make_dataset``.

::

    lunar dataset --n 1000                                   # soft landing
    lunar dataset --env LunarPinpointLanding-v2 --n 200      # pinpoint, noisy expert
    lunar dataset --n 1000 --minari optimal-v0   # + lunar/<env>/optimal-v0

The datasets themselves are built by :func:`agents.imitation.dataset.generate` and read by
:func:`agents.imitation.data.load_dataset`; ``--minari NAME`` also writes the certified flights
as the Minari dataset ``lunar/<env>/<NAME>`` (:mod:`agents.imitation.minari_data`).
"""

from __future__ import annotations

import argparse
import json
import os

from agents.imitation.dataset import DEFAULT_ENV_ID, DEFAULT_OUT, generate
from agents.imitation.families.pinpoint import PINPOINT_ACTION_NOISE, PINPOINT_TOLERANCES
from optimizers.common.cli import (
    check_env,
    count_type,
    output_file_type,
    ray_address_type,
    real_type,
    seed_type,
    user_input_errors,
)

__all__ = ["main"]

#: largest --n (trajectories held in memory until the dataset is written)
MAX_TRAJECTORIES = 1_000_000
#: largest --workers
MAX_WORKERS = 1024
#: largest --n-steps (RK4 steps of each solve)
MAX_STEPS = 100_000


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (``python -m agents.imitation.make_dataset``)."""
    import yaml

    p = argparse.ArgumentParser(prog="lunar dataset",
                                description="Datasets of certified optimal landings for "
                                            "imitation learning.")
    p.add_argument("--env", default=DEFAULT_ENV_ID)
    p.add_argument("--env-kwargs", nargs="*", default=[], metavar="KEY=VALUE",
                   help="env constructor arguments (values parsed as YAML)")
    p.add_argument("--n", type=count_type(1, MAX_TRAJECTORIES), default=1000,
                   help=f"number of trajectories, 1 to {MAX_TRAJECTORIES} (default 1000)")
    p.add_argument("--seed", type=seed_type, default=0,
                   help="seed of the initial-state draw, 0 to 2**63 - 1 (default 0)")
    p.add_argument("--out", type=output_file_type, default=None,
                   help=f"output .npz (default data/imitation/<env>_n<n>_seed<seed>.npz; "
                        f"{DEFAULT_OUT} for the defaults)")
    p.add_argument("--workers", type=count_type(1, MAX_WORKERS), default=2)
    p.add_argument("--address", type=ray_address_type, default=None,
                   help="Ray cluster for the shards ('auto', 'host:port', 'local'); default "
                        "$RAY_ADDRESS, else --workers local processes")
    p.add_argument("--shard-size", type=count_type(1, MAX_TRAJECTORIES), default=50)
    p.add_argument("--n-steps", type=count_type(2, MAX_STEPS), default=400,
                   help="solver RK4 grid")
    p.add_argument("--check", default="doubling", choices=("grid", "doubling", "reference"))
    p.add_argument("--tol-radius-m", type=real_type(positive=True), default=None,
                   help="certification tolerance (default 1e-3 m soft landing, "
                        f"{PINPOINT_TOLERANCES['radius_m']:g} m gate miss pinpoint)")
    p.add_argument("--tol-speed-m-s", type=real_type(positive=True), default=None,
                   help="certification tolerance (default 1e-3 m/s soft landing, "
                        f"{PINPOINT_TOLERANCES['speed_m_s']:g} m/s gate speed pinpoint)")
    p.add_argument("--noise", type=real_type(0.0), default=None,
                   help="pinpoint: standard deviation of the action noise on the expert's "
                        f"flights (default {PINPOINT_ACTION_NOISE:g}; 0: the optimal "
                        "trajectories themselves)")
    p.add_argument("--minari", default=None, metavar="NAME",
                   help="also write the certified flights as the Minari dataset "
                        "lunar/<env>/<NAME> (e.g. optimal-v0) in $MINARI_DATASETS_PATH "
                        "(default ~/.minari/datasets); needs the 'minari' extra")
    p.add_argument("--minari-overwrite", action="store_true",
                   help="replace an existing local Minari dataset of that id")
    p.add_argument("--no-progress", action="store_true")
    args = p.parse_args(argv)
    env_kwargs = {}
    for item in args.env_kwargs:
        if "=" not in item:
            p.error(f"--env-kwargs {item!r}: expected KEY=VALUE")
        k, v = item.split("=", 1)
        env_kwargs[k] = yaml.safe_load(v)
    with user_input_errors(p):
        check_env(args.env, env_kwargs)
    if args.out is None:
        args.out = f"data/imitation/{args.env}_n{args.n}_seed{args.seed}.npz"
    minari_id = None
    if args.minari is not None:
        from agents.imitation.minari_data import minari_dataset_id

        try:
            minari_id = minari_dataset_id(args.env, args.minari)
        except ValueError as exc:
            p.error(f"--minari: {exc}")
        try:
            import minari
        except ImportError:
            p.error("--minari needs the 'minari' extra: pip install -e '.[minari]'")
        if minari_id in minari.list_local_datasets() and not args.minari_overwrite:
            p.error(f"--minari {args.minari}: the Minari dataset {minari_id!r} exists locally; "
                    "add --minari-overwrite or choose another name/version")
    from optimizers.common.executor import RAY_ADDRESS_ENV, get_executor

    executor = (get_executor(args.address, args.workers)
                if args.address or os.environ.get(RAY_ADDRESS_ENV) else None)
    try:
        ds = generate(args.out, env_id=args.env, env_kwargs=env_kwargs, n=args.n,
                      seed=args.seed, n_workers=args.workers, shard_size=args.shard_size,
                      n_steps=args.n_steps, check=args.check, tol_radius_m=args.tol_radius_m,
                      tol_speed_m_s=args.tol_speed_m_s, progress=not args.no_progress,
                      executor=executor, action_noise=args.noise)
    finally:
        if executor is not None:
            executor.close()
    assert ds is not None
    print(json.dumps(ds.summary(), indent=1))
    print(f"Written: {args.out}")
    if minari_id is not None:
        import time

        from agents.imitation.minari_data import write_minari

        t0 = time.perf_counter()
        mds = write_minari(ds, minari_id, source=args.out, overwrite=args.minari_overwrite)
        print(f"Minari dataset {minari_id}: {mds.total_episodes} episodes, "
              f"{mds.total_steps} steps, ref_min_score {mds.storage.metadata['ref_min_score']:.4f},"
              f" ref_max_score {mds.storage.metadata['ref_max_score']:.4f} "
              f"({time.perf_counter() - t0:.1f} s)")
    return 0




if __name__ == "__main__":
    raise SystemExit(main())
