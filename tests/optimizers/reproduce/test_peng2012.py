"""Quick reproduction of [001] (GPM + direct shooting) and the open-loop replay in the env."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from lunar_env import get_scenario
from optimizers.problems.pinpoint import PinpointOCP
from optimizers.reproduce import peng2012
from optimizers.transcription.serial import solve_serial


def _quick_run(tmp_path, *flags: str) -> tuple[dict, dict]:
    """``--quick`` run with ``flags``; checks what every quick run writes, returns the JSON's
    measured and nominal parts."""
    out = tmp_path / "fig"
    js = tmp_path / "peng2012.json"
    assert peng2012.main(["--quick", *flags, "--json", str(js), "--out", str(out)]) == 0
    d = json.loads(js.read_text())
    assert set(d) == {"published", "measured"}
    pub, mea = d["published"], d["measured"]
    assert pub["tf_s"] == 556.0648 and pub["fuel_kg"] == 283.7065
    nom = mea["nominal"]
    assert nom["converged"]
    # fuel is the constant mass flow times tf
    assert math.isclose(nom["fuel_kg"], 1500 / (300 * 9.8) * nom["tf_s"], rel_tol=1e-12)
    assert len(nom["gpm"]["alpha_deg"]) == 6
    rg = mea["random_guesses"]
    assert rg["n"] == 1 and rg["n_converged"] == 1
    assert {"n", "n_converged", "runs"} <= set(mea["shooting_alone"])
    for name in ("fig3_trajectory.png", "fig4_velocity.png", "fig5_thrust_angles.png"):
        assert (out / name).stat().st_size > 0
    return mea, nom


def test_quick_reproduction_without_the_checks_json_structure(tmp_path):
    """The quick twin of :func:`test_quick_reproduction_json_structure` (``slow``): the same
    command without the dense-collocation, Pontryagin and environment checks, which the
    default run checks on the same problem elsewhere
    (``tests/optimizers/test_certification.py::test_pinpoint_serial_solution_against_dense_
    collocation``, ``tests/optimizers/test_pinpoint_feedback.py::test_forward_extremal_matches_
    the_certified_backward_solution``, :func:`test_shooting_solution_lands_in_env`)."""
    mea, nom = _quick_run(tmp_path, "--no-dense", "--no-env")
    assert not {"dense_collocation", "certificate", "pontryagin", "env_replay"} & set(mea)
    assert abs(nom["tf_s"] - 553.342) < 0.01
    assert nom["reference_replay_dop853"]["position_m"] < 10.0


@pytest.mark.slow
def test_quick_reproduction_json_structure(tmp_path):
    mea, _ = _quick_run(tmp_path)
    # the serial result is the converged optimum of the same problem (dense LG collocation)
    dense = mea["dense_collocation"]
    assert abs(dense["serial_minus_reference_tf_s"]) < 0.01
    # ... and of the indirect (Pontryagin) solution, an independent method
    pmp = mea["pontryagin"]
    assert pmp["success"] and abs(pmp["serial_minus_pontryagin_tf_s"]) < 0.01
    assert pmp["max_abs_u_m_s"] < 110 and pmp["max_abs_w_m_s"] < 110
    ev = mea["env_replay"]
    assert "skipped" not in ev, ev
    assert ev["miss_distance_m"] < 10.0 and ev["touchdown_speed_m_s"] < 0.5


def test_shooting_solution_lands_in_env():
    ocp = PinpointOCP(get_scenario("peng2012"))
    res = solve_serial(ocp, form="lifted", n_rk4_per_segment=4)
    assert res.success
    ev = peng2012.replay_in_env(res, ocp)
    assert ev["is_success"]
    assert ev["miss_distance_m"] < 10.0, ev
    assert ev["touchdown_speed_m_s"] < 0.5, ev
    # fuel: the env burns until the engine cut-off at the speed minimum, i.e. ~tf
    assert abs(ev["fuel_used_kg"] - res.fuel_kg) < 0.5


def test_cli_rejects_negative_guesses():
    with pytest.raises(SystemExit):
        peng2012.main(["--guesses", "-1"])


def test_published_table_is_consistent():
    # table 2's fuel is 1500/(300·9.8)·tf for each run (the paper's own arithmetic)
    rg = peng2012.PUBLISHED["random_guesses"]
    np.testing.assert_allclose(np.array(rg["fuel_kg"]),
                               1500 / (300 * 9.8) * np.array(rg["tf_s"]), atol=6e-4)
