import numpy as np
import pytest

from calib.loading import load_robot


@pytest.fixture(scope="session")
def puma():
    return load_robot()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    """The on-disk cache (:mod:`acq.cache`) in a folder of this test run, not the user's (subprocesses inherit it)."""
    import os
    old = os.environ.get("ROBOCAL_CACHE_DIR")
    os.environ["ROBOCAL_CACHE_DIR"] = str(tmp_path_factory.mktemp("robocal-cache"))
    yield
    if old is None:
        os.environ.pop("ROBOCAL_CACHE_DIR", None)
    else:
        os.environ["ROBOCAL_CACHE_DIR"] = old
