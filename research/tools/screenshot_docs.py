"""Screenshots of the built documentation site in headless Chromium (for review, outside the
product): the index, an env page, the uncertainty page and a results page.

    python research/tools/screenshot_docs.py [--site docs/_build/html] \
        [--out research/docs_screenshots]
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PAGES = {"index.png": "index.html",
         "env_LunarSoftLanding-v0.png": "envs/LunarSoftLanding-v0.html",
         "env_LunarPinpointLanding-v2.png": "envs/LunarPinpointLanding-v2.html",
         "uncertainty.png": "envs/uncertainty.html",
         "results_campaigns.png": "results/campaigns.html"}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--site", type=Path, default=ROOT / "docs" / "_build" / "html")
    ap.add_argument("--out", type=Path, default=ROOT / "research" / "docs_screenshots")
    ap.add_argument("--height", type=int, default=2400)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as profile:
        for name, page in PAGES.items():
            subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu",
                            "--disable-background-networking", "--disable-component-update",
                            "--disable-sync", "--no-first-run", f"--user-data-dir={profile}",
                            "--hide-scrollbars", f"--window-size=1400,{args.height}",
                            f"--screenshot={args.out / name}",
                            (args.site / page).resolve().as_uri()],
                           check=True, capture_output=True, timeout=180)
            print(args.out / name)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
