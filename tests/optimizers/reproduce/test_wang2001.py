"""``python -m optimizers.reproduce wang2001 --quick`` (default run): tables, JSON and plots."""

import json

import pytest

from optimizers.reproduce.wang2001 import PUBLISHED, main


def test_quick_reproduction(tmp_path):
    out = tmp_path / "wang2001.json"
    assert main(["--quick", "--json", str(out), "--out", str(tmp_path / "plots")]) == 0
    d = json.loads(out.read_text())
    assert set(d) == {"published", "measured"}
    assert d["published"] == json.loads(json.dumps(PUBLISHED))
    rows = d["measured"]["rows"]
    assert [(r["mode"], r["k"]) for r in rows] == [
        (m, row["k"]) for m in ("transfer", "interception") for row in PUBLISHED[m]]
    for r in rows:
        c = r["certified"]
        assert c["miss_m"] < 1.0 and c["branch"] == "cw (own sense) N=0"
        assert r["verdict"]
        # no optimiser run may beat the certified global minimum
        for key in ("ea_printed", "ea_80"):
            assert min(r[key]["cost"]) >= c["cost"] - 1e-9
            assert len(r[key]["cost"]) == 2
    by = {(r["mode"], r["k"]): r for r in rows}
    # rows that reproduce to the printed digits (targets printed in [004])
    assert by[("interception", 0.003)]["certified"]["cost"] == pytest.approx(12.186, abs=2e-3)
    assert by[("interception", 0.03)]["certified"]["cost"] == pytest.approx(40.593, abs=2e-3)
    assert by[("transfer", 0.03)]["certified"]["cost"] == pytest.approx(53.103, abs=2e-3)
    assert by[("interception", 0.003)]["verdict"] == "reproduced"
    # a printed value below anything physically possible is refuted, with the evidence
    assert by[("interception", 3e-5)]["verdict"].startswith("J refuted")
    assert by[("interception", 3e-5)]["k0_minimum_dv"] > 9.026
    # a printed value that is another K's: Table 1's first J is J(T) with K = 3e-5
    assert by[("transfer", 0.0003)]["checks"]["cost_matches_other_k"]["k"] == 3e-5
    # with T below the one-revolution arcs the EA finds every certified optimum
    for r in rows:
        assert min(r["ea_80_single_rev_bounds"]["cost"]) >= r["certified"]["cost"] - 1e-9
    assert len(d["measured"]["plots"]) == 3
    for path in d["measured"]["plots"]:
        assert (tmp_path / "plots").as_posix() in path
