"""Issue 31: which part of the `standard` navigation errors breaks the pinpoint agents.

``python research/notes/scripts/issue-31-navigation-parts.py OUT_DIR LAW... [--cases N]``

Flies the laws (campaign specs, e.g. ``ppo:runs/pin/nominal``) on ``LunarPinpointLanding-v2``
under `standard` with every error group zeroed except one part of the navigation model: the
whole navigation set with the landing radar locking at 3, 6 or 12 km, then its bias alone,
its noise alone, the position bias alone, the velocity bias alone, and the position bias
along each axis alone. One campaign per part (``python -m agents.campaign``, the same cases
for every part, 2 workers); the per-part summaries (success, its 95 % interval, gate speed
p50, miss p50 / p99) are merged into ``OUT_DIR/navigation_parts.json``, written atomically,
and printed as a table. A part whose campaign JSON already exists in ``OUT_DIR`` is not
flown again (re-running after a kill resumes).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from agents.common.runs import write_text_atomic

Z3 = [0.0, 0.0, 0.0]
#: every group of `standard` but navigation, zeroed
NO_ENTRY_NO_PLANT = {"entry_position_m": Z3, "entry_velocity_m_s": Z3, "thrust_scale": 0.0,
                     "isp_scale": 0.0, "misalignment_rad": 0.0, "mass_kg": 0.0}
NO_NOISE = {"nav_position_noise_m": Z3, "nav_velocity_noise_m_s": Z3}
NO_BIAS = {"nav_position_bias_m": Z3, "nav_velocity_bias_m_s": Z3}


def parts() -> dict[str, dict]:
    """The uncertainty dicts of the parts, by name (each on top of `standard`)."""
    from lunar_env.uncertainty import get_uncertainty

    position_bias_m = get_uncertainty("standard").nav_position_bias_m  # up, down, cross
    out: dict[str, dict] = {}
    for km in (3, 6, 12):
        out[f"navigation, radar lock {km} km"] = {"radar_altitude_m": 1000.0 * km}
    out["bias alone"] = dict(NO_NOISE)
    out["noise alone"] = dict(NO_BIAS)
    out["position bias alone"] = {**NO_NOISE, "nav_velocity_bias_m_s": Z3}
    out["velocity bias alone"] = {**NO_NOISE, "nav_position_bias_m": Z3}
    for i, axis in enumerate(("up", "downrange", "crossrange")):
        bias = [0.0, 0.0, 0.0]
        bias[i] = float(position_bias_m[i])
        out[f"position bias, {axis} alone"] = {**NO_NOISE, "nav_velocity_bias_m_s": Z3,
                                               "nav_position_bias_m": bias}
    return {name: {"base": "standard", **NO_ENTRY_NO_PLANT, **d} for name, d in out.items()}


def slug(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name).strip("_")


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("laws", nargs="+")
    ap.add_argument("--cases", type=int, default=200)
    args = ap.parse_args(argv)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    merged: dict[str, dict] = {}
    for name, unc in parts().items():
        js = args.out_dir / f"{slug(name)}.json"
        if not js.exists():
            print(f"-- {name}", flush=True)
            subprocess.run([sys.executable, "-m", "agents.campaign", "--env",
                            "LunarPinpointLanding-v2", "--uncertainty", json.dumps(unc),
                            "--cases", str(args.cases), "--chunk", "100", "--workers", "2",
                            "--no-plots", "--scales", "--out", str(args.out_dir / slug(name)),
                            "--json", str(js), "--laws", *args.laws], check=True)
        laws = json.loads(js.read_text())["laws"]
        merged[name] = {"uncertainty": unc, "laws": {
            law: {k: s[k] for k in ("cases", "success_rate", "success_ci95",
                                    "touchdown_speed_p50_m_s", "miss_p50_m", "miss_p99_m")}
            for law, s in laws.items()}}
    out = args.out_dir / "navigation_parts.json"
    write_text_atomic(out, json.dumps(merged, indent=1))
    print(f"\n{'part':38s}" + "".join(f"{law.rstrip('/').split('/')[-1]:>26s}"
                                        for law in args.laws))
    for name, row in merged.items():
        cells = [f"{100 * s['success_rate']:5.1f} % (v {s['touchdown_speed_p50_m_s']:6.1f})"
                 for s in row["laws"].values()]
        print(f"{name:38s}" + "".join(f"{c:>26s}" for c in cells))
    print(out)


if __name__ == "__main__":
    main(sys.argv[1:])
