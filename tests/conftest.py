import numpy as np
import pytest

from calib.loading import load_robot


@pytest.fixture(scope="session")
def puma():
    return load_robot()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
