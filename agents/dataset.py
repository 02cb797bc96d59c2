"""Command line of the optimal-landing datasets: ``python -m agents.dataset``.

::

    python -m agents.dataset --n 1000                                   # soft landing
    python -m agents.dataset --env LunarPinpointLanding-v2 --n 200      # pinpoint, noisy expert

The datasets themselves are built by :func:`agents.imitation.dataset.generate` and read by
:func:`agents.imitation.data.load_dataset`.
"""

from __future__ import annotations

import argparse
import json
import os

from agents.experts.pinpoint.data import PINPOINT_ACTION_NOISE, PINPOINT_TOLERANCES
from agents.imitation.dataset import DEFAULT_ENV_ID, DEFAULT_OUT, generate

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point (``python -m agents.dataset``)."""
    import yaml

    p = argparse.ArgumentParser(prog="python -m agents.dataset",
                                description="Datasets of certified optimal landings for "
                                            "imitation learning.")
    p.add_argument("--env", default=DEFAULT_ENV_ID)
    p.add_argument("--env-kwargs", nargs="*", default=[], metavar="KEY=VALUE",
                   help="env constructor arguments (values parsed as YAML)")
    p.add_argument("--n", type=int, default=1000, help="number of trajectories")
    p.add_argument("--seed", type=int, default=0, help="seed of the initial-state draw")
    p.add_argument("--out", default=None,
                   help=f"output .npz (default data/imitation/<env>_n<n>_seed<seed>.npz; "
                        f"{DEFAULT_OUT} for the defaults)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--address", default=None,
                   help="Ray cluster for the shards ('auto', 'host:port', 'local'); default "
                        "$RAY_ADDRESS, else --workers local processes")
    p.add_argument("--shard-size", type=int, default=50)
    p.add_argument("--n-steps", type=int, default=400, help="solver RK4 grid")
    p.add_argument("--check", default="doubling", choices=("grid", "doubling", "reference"))
    p.add_argument("--tol-radius-m", type=float, default=None,
                   help="certification tolerance (default 1e-3 m soft landing, "
                        f"{PINPOINT_TOLERANCES['radius_m']:g} m gate miss pinpoint)")
    p.add_argument("--tol-speed-m-s", type=float, default=None,
                   help="certification tolerance (default 1e-3 m/s soft landing, "
                        f"{PINPOINT_TOLERANCES['speed_m_s']:g} m/s gate speed pinpoint)")
    p.add_argument("--noise", type=float, default=None,
                   help="pinpoint: standard deviation of the action noise on the expert's "
                        f"flights (default {PINPOINT_ACTION_NOISE:g}; 0: the optimal "
                        "trajectories themselves)")
    p.add_argument("--no-progress", action="store_true")
    args = p.parse_args(argv)
    env_kwargs = {}
    for item in args.env_kwargs:
        if "=" not in item:
            p.error(f"--env-kwargs {item!r}: expected KEY=VALUE")
        k, v = item.split("=", 1)
        env_kwargs[k] = yaml.safe_load(v)
    if args.out is None:
        args.out = f"data/imitation/{args.env}_n{args.n}_seed{args.seed}.npz"
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
    return 0




if __name__ == "__main__":
    raise SystemExit(main())
