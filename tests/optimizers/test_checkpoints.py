"""Optimiser checkpoints (ASAGA) under kills and damage: a solve SIGKILLed at a seeded random
point resumes to the uninterrupted result, and a damaged checkpoint is named.
"""

from __future__ import annotations

import random

import numpy as np
import pytest
from proc_helpers import kill_point, kill_seed, noted, python, sigkill_when

# ------------------------------------------------------------------------------------- optimisers

_ASAGA_CLI = """
    import sys
    from optimizers.evolutionary.asaga import ASAGA
    from optimizers.problems.landing import PlanarLandingProblem
    ASAGA(n_generations=int(sys.argv[2])).solve(PlanarLandingProblem(), seed=5,
                                                checkpoint=sys.argv[1], checkpoint_every=1)
"""


def _kill_and_resume_asaga(tmp_path, n_gen, kseed):
    from optimizers.evolutionary.asaga import ASAGA
    from optimizers.problems.landing import PlanarLandingProblem

    ck = tmp_path / "asaga.pkl"
    delay = random.Random(kseed).uniform(0.0, 0.3)
    where = kill_point("the first ASAGA checkpoint", kseed, delay)
    proc = python(_ASAGA_CLI, str(ck), str(n_gen))
    sigkill_when(proc, ck.exists, delay)
    with noted(where):
        problem = PlanarLandingProblem()
        resumed = ASAGA(n_generations=n_gen).solve(problem, seed=5, checkpoint=ck)
        full = ASAGA(n_generations=n_gen).solve(problem, seed=5)
        np.testing.assert_array_equal(resumed.x, full.x)
        np.testing.assert_array_equal(resumed.history, full.history)
        assert resumed.n_fevals == full.n_fevals and resumed.success == full.success


def test_optimiser_killed_at_a_random_point_resumes(tmp_path):
    _kill_and_resume_asaga(tmp_path, 30, kill_seed(18))


@pytest.mark.slow
@pytest.mark.parametrize("trial", range(5))
def test_optimiser_killed_at_random_points_slow(tmp_path, trial):
    _kill_and_resume_asaga(tmp_path, 80, trial)


def test_damaged_optimiser_checkpoint_is_named(tmp_path):
    from optimizers.evolutionary.asaga import ASAGA
    from optimizers.problems.landing import PlanarLandingProblem

    ck = tmp_path / "asaga.pkl"
    ASAGA(n_generations=2).solve(PlanarLandingProblem(), seed=5, checkpoint=ck)
    for cut in (0, 17, ck.stat().st_size // 2):
        data = ck.read_bytes()
        ck.write_bytes(data[:cut])
        with pytest.raises(ValueError, match=f"checkpoint {ck} is damaged"):
            ASAGA(n_generations=2).solve(PlanarLandingProblem(), seed=5, checkpoint=ck)
        ck.write_bytes(data)


def _interrupt_right_after_create(monkeypatch):
    """``os.open`` creates the file, then a signal's exception arrives before it returns: the
    moment a name known only after creation (``tempfile.mkstemp``) would leave an orphan."""
    import os

    real_open = os.open

    def open_then_interrupt(*args, **kwargs):
        fd = real_open(*args, **kwargs)
        os.close(fd)
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "open", open_then_interrupt)


def test_an_interrupt_as_the_temporary_file_appears_leaves_no_file(tmp_path, monkeypatch):
    from optimizers.common.checkpoint import atomic_write_bytes

    target = tmp_path / "result.json"
    target.write_bytes(b"old")
    _interrupt_right_after_create(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_bytes(target, b"new")
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.json"]
    assert target.read_bytes() == b"old"


def test_an_interrupt_as_a_stores_identity_is_written_leaves_no_file(tmp_path, monkeypatch):
    from optimizers.common.store import ResultStore

    _interrupt_right_after_create(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        ResultStore(tmp_path / "store", identity={"a": 1}, fmt="json")
    monkeypatch.undo()
    assert not [p for p in (tmp_path / "store").rglob("*") if p.is_file()]
    ResultStore(tmp_path / "store", identity={"a": 1}, fmt="json")  # and it opens afterwards
