import numpy as np
import pytest

from calib.robot import load_robot


@pytest.fixture(scope="session")
def puma():
    return load_robot()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
