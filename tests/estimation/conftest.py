"""Fixtures of the estimation tests."""

import numpy as np
import pytest


@pytest.fixture(scope="session")
def paper_ramp():
    """§4.1 input: H ramps linearly 0 -> 1e5 A/m over 6 s, sampled every 1 ms."""
    dt = 1e-3
    time = np.arange(0.0, 6.0 + dt / 2, dt)
    return time, 1e5 * time / 6.0, dt
