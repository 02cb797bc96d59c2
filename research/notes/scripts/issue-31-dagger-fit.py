"""How well a DAgger run's students fit its teacher's labels, by altitude band (issue 31).

For each iteration k >= 1: the RMS error (action units, per channel: α, β, throttle) of the
policy of iteration k - 1 on the labels of iteration k (states it had not been trained on:
its own roll-outs, labelled by the teacher) against that of the policy of iteration k, which
was trained on them. A large first and small second is the distribution shift DAgger closes
iteration by iteration; a large second would be a teacher the network cannot represent.

    python research/notes/scripts/issue-31-dagger-fit.py runs/imitation/<dagger run dir>
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

BANDS = [(0.0, 0.02), (0.02, 0.1), (0.1, 0.5), (0.5, 2.0)]  # altitude / initial altitude


def main() -> None:
    from stable_baselines3 import PPO

    from agents.imitation.policy import policy_inputs

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path)
    args = ap.parse_args()
    hp = yaml.safe_load((args.run_dir / "config.yml").read_text())
    env_id = yaml.safe_load((args.run_dir / "args.yml").read_text())["env"]
    # config.yml holds the run's env arguments: the dataset's with the run's merged over them
    inputs = policy_inputs(env_id, dict(hp.get("env_kwargs") or {}), hp.get("obs_features"))
    ck = args.run_dir / "checkpoints"
    models: dict[int, PPO] = {}  # each checkpoint loaded once (it serves two iterations)
    k = 1
    while (ck / f"dagger_iter_{k}.zip").exists():
        with np.load(args.run_dir / "labels" / f"iter_{k:03d}.npz") as z:
            obs, act = z["obs"], z["actions"]
        x = inputs(obs)
        print(f"labels of iteration {k} ({len(obs)}):")
        for who in (k - 1, k):
            if who not in models:
                models[who] = PPO.load(ck / f"dagger_iter_{who}.zip", device="cpu")
            model = models[who]
            err = model.predict(x, deterministic=True)[0] - act
            cells = []
            for lo, hi in BANDS:
                s = (obs[:, 0] >= lo) & (obs[:, 0] < hi)
                rms = np.sqrt(np.mean(err[s] ** 2, axis=0)) if s.any() else np.full(3, np.nan)
                cells.append(f"h/h0 [{lo}, {hi}): " + " ".join(f"{v:.3f}" for v in rms))
            tag = "before (not trained on them)" if who < k else "after (trained on them) "
            print(f"  policy of iteration {who} {tag}  " + " | ".join(cells))
        k += 1


if __name__ == "__main__":
    main()
