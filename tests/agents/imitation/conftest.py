"""Fixtures shared by the imitation tests."""

import os

import pytest


@pytest.fixture(scope="module")
def minari_dir(tmp_path_factory):
    """A private Minari datasets directory (never the user's ~/.minari)."""
    pytest.importorskip("minari")
    path = tmp_path_factory.mktemp("minari")
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(path)
    yield path
    if old is None:
        os.environ.pop("MINARI_DATASETS_PATH", None)
    else:
        os.environ["MINARI_DATASETS_PATH"] = old
