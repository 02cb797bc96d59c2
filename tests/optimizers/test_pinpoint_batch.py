"""Per-case pinpoint optima in batches (optimizers.transcription.batch): problems built once per
scenario fingerprint, the warm-started chain, input order and the caller's store hook."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import optimizers.transcription.batch as batch
from lunar_env import get_scenario
from optimizers.common.executor import LocalExecutor

STORED: list = []


def _record(key, opt) -> None:
    """Module-level store hook (executors refuse closures)."""
    STORED.append((key, opt))


def test_problems_are_keyed_by_the_scenario_fingerprint():
    sc = get_scenario("peng2012")
    twin = dataclasses.replace(sc)  # equal, but another object (another id)
    assert twin is not sc and twin == sc
    assert batch.scenario_fingerprint(twin) == batch.scenario_fingerprint(sc)
    # equal scenarios share one problem
    assert batch.env_ocp(twin) is batch.env_ocp(sc)
    assert batch.replan_ocp(twin) is batch.replan_ocp(sc)
    # a different scenario gets its own problem, never a stale one
    other = dataclasses.replace(sc, uw_bound_m_s=sc.uw_bound_m_s + 10.0)
    assert batch.scenario_fingerprint(other) != batch.scenario_fingerprint(sc)
    ocp = batch.env_ocp(other)
    assert ocp is not batch.env_ocp(sc)
    assert ocp.scenario == other and batch.env_ocp(sc).scenario == sc
    assert ocp.min_altitude_m == other.target.altitude_m
    re = batch.replan_ocp(other)
    assert re.scenario == dataclasses.replace(other, tf_bounds_s=(1.0, other.tf_bounds_s[1]))
    assert batch.replan_ocp(sc).scenario.uw_bound_m_s == sc.uw_bound_m_s
    # the key is the value, not the object: a fresh copy of `other` finds other's problem
    assert batch.env_ocp(dataclasses.replace(other)) is ocp


def test_many_plants_keep_a_bounded_number_of_problems_and_solvers():
    """Bug fixed: every plant's problem and solver (~300 MB of CasADi NLPs once
    built) stayed in the process-wide caches; 52 plants grew a process to 14-17 GB. Now the
    most recently used are kept, the oldest evicted, and a fetch still returns the live one."""
    from optimizers.transcription import serial

    sc = get_scenario("peng2012")
    plants = [dataclasses.replace(sc, uw_bound_m_s=sc.uw_bound_m_s + k) for k in range(1, 25)]
    solvers = []
    for plant in plants:
        ocp = batch.env_ocp(plant)
        solvers.append(serial.get_solver(ocp, **batch.SOLVER_OPTIONS))  # not built: cheap
        assert len(batch._OCPS) <= batch.MAX_CACHED_OCPS
        assert len(serial._SOLVERS) <= serial.MAX_CACHED_SOLVERS
    last = plants[-1]
    assert serial.get_solver(batch.env_ocp(last), **batch.SOLVER_OPTIONS) is solvers[-1]
    assert batch.env_ocp(last).scenario == last
    # an evicted plant is rebuilt for its own scenario, never another plant's
    first = batch.env_ocp(plants[0])
    assert first.scenario == plants[0]
    assert serial.get_solver(first, **batch.SOLVER_OPTIONS).ocp is first


def _fake_solve_case(scenario, x0_nd, warm=None):
    """Stands in for the NLP solve: row k (its mass column holds k) 'succeeds' unless k is 3,
    and records which case warm-started it."""
    k = int(x0_nd[6])
    return batch.PinpointOptimum(k != 3, float(k), 100.0 + k,
                                 message="cold" if warm is None else f"warm {warm.fuel_kg:g}")


def _states(n: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    states = np.tile(rng.normal(size=7), (n, 1)) + 0.01 * rng.normal(size=(n, 7))
    states[:, 6] = np.arange(n)  # the fake solver reads the row's id here
    return states


def test_solve_many_chains_warm_starts_and_keeps_input_order(monkeypatch):
    monkeypatch.setattr(batch, "solve_case", _fake_solve_case)
    states = _states(7)
    STORED.clear()
    keys = [f"key{k}" for k in range(7)]
    opts = batch.solve_many(get_scenario("peng2012"), states, progress=False, store=_record,
                            store_keys=keys)
    assert [o.fuel_kg for o in opts] == list(range(7))
    # each case was stored once, under its own key, as it was solved (chain order)
    assert sorted(STORED, key=lambda s: s[0]) == sorted(zip(keys, opts, strict=True),
                                                        key=lambda s: s[0])
    # warm start: the previous success along the nearest-neighbour chain (3 fails: skipped)
    order = batch.nearest_neighbour_order(states)
    assert [STORED[j][0] for j in range(7)] == [keys[i] for i in order]
    assert [opts[i].message for i in order] == _expected_messages(order)


def _expected_messages(chain) -> list[str]:
    """What _fake_solve_case reports along a chain: cold first, then warm from the last
    success (case 3 fails, so it never warm-starts another)."""
    out, prev = [], None
    for i in chain:
        out.append("cold" if prev is None else f"warm {prev:g}")
        if i != 3:
            prev = float(i)
    return out


def test_solve_many_in_chunks_on_an_executor(monkeypatch):
    monkeypatch.setattr(batch, "solve_case", _fake_solve_case)
    states = _states(9)
    STORED.clear()
    ex = LocalExecutor(0)  # in this process, through the executor's task path
    try:
        opts = batch.solve_many(get_scenario("peng2012"), states, progress=False, executor=ex,
                                store=_record, store_keys=list(range(9)))
    finally:
        ex.close()
    assert [o.fuel_kg for o in opts] == list(range(9))
    assert sorted(k for k, _ in STORED) == list(range(9))
    # four chunks of the chain (4 x the executor's workers, at least one), each its own chain
    chunks = np.array_split(batch.nearest_neighbour_order(states), 4)
    assert len(chunks) == 4
    for c in chunks:
        assert [opts[i].message for i in c] == _expected_messages(c)
    assert sum(o.message == "cold" for o in opts) >= 4


def test_solve_many_bad_inputs():
    sc = get_scenario("peng2012")
    with pytest.raises(ValueError, match="expected"):
        batch.solve_many(sc, np.zeros((2, 5)), progress=False)
    with pytest.raises(ValueError, match="n_workers"):
        batch.solve_many(sc, np.zeros((2, 7)), n_workers=0, progress=False)
    with pytest.raises(ValueError, match="store_keys"):
        batch.solve_many(sc, np.zeros((2, 7)), progress=False, store=_record, store_keys=["a"])
    assert batch.solve_many(sc, np.zeros((0, 7)), progress=False) == []
