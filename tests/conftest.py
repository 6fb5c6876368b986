import numpy as np
import pytest
from hypothesis import HealthCheck, settings

from shared.robot.model import default_robot

settings.register_profile("project", deadline=None, suppress_health_check=[HealthCheck.too_slow],
                          derandomize=True)
settings.load_profile("project")


@pytest.fixture(scope="session")
def robot():
    return default_robot()


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
