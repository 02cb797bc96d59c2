"""A user's law, in a module of their own outside the library, flies a campaign through the
``lunar`` command line (``--import``), in worker processes too, beside the library's laws."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "apollo_in_15_lines.py"


def test_the_fifteen_line_apollo_flies_as_the_library_law():
    """On the constant-thrust planar engine the example law is the library's ``apollo``: the same
    landings, the same propellant (to the library law's measuring its engine with the IMU,
    which in the nominal world reads the nominal thrust to a few parts per million)."""
    from guidance import registry
    from guidance.flight import fly
    from guidance.laws.apollo import AugmentedApolloLaw
    from guidance.registry import import_law_modules

    import_law_modules([str(EXAMPLE)])
    mod = sys.modules.pop("lunar_user_laws.apollo_in_15_lines")  # imported once, here
    registry._REGISTRY.pop("apollo-15")  # a test's law does not stay registered
    kw = {"dt_s": 2.5}
    a = fly("LunarSoftLanding-v0", mod.Apollo(), 6, seed=3, env_kwargs=kw)
    b = fly("LunarSoftLanding-v0", AugmentedApolloLaw(), 6, seed=3, env_kwargs=kw)
    np.testing.assert_array_equal(a.is_success, b.is_success)
    np.testing.assert_allclose(a.fuel_used_kg, b.fuel_used_kg, rtol=1e-5)


def test_a_users_law_flies_a_campaign_from_the_command_line(tmp_path):
    out = tmp_path / "camp"
    res = subprocess.run(
        [sys.executable, "-m", "lunar", "campaign", "--import", str(EXAMPLE), "--laws",
         "apollo-15", "apollo", "--env", "LunarSoftLanding-v0", "--env-kwargs",
         '{"dt_s": 2.5}', "--cases", "4", "--chunk", "2", "--scales", "--workers", "1",
         "--uncertainty", "none",
         "--no-plots", "--out", str(out)],
        capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-3000:]
    summary = json.loads((out / "campaign.json").read_text())
    assert set(summary["laws"]) == {"apollo-15", "apollo"}
    mine, lib = summary["laws"]["apollo-15"], summary["laws"]["apollo"]
    assert mine["cases"] == 4 and mine["successes"] == lib["successes"]
    listed = subprocess.run([sys.executable, "-m", "lunar", "campaign", "--import",
                             str(EXAMPLE), "--list-laws"], capture_output=True, text=True,
                            timeout=120, cwd=tmp_path)
    assert listed.returncode == 0 and "apollo-15" in listed.stdout


def test_an_unknown_law_module_is_one_line_naming_it(tmp_path):
    res = subprocess.run([sys.executable, "-m", "lunar", "campaign", "--import",
                          str(tmp_path / "nowhere.py"), "--laws", "apollo"],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "nowhere.py" in res.stderr.strip().splitlines()[-1]
