"""Shared fixtures. Tests mirror the package: tests/model (physics, integrator), tests/envs (task,
compiled step, environments), tests/benchmark (the seed paper's tasks, the command line),
tests/integrations, tests/agents; tests/test_behaviour.py and tests/test_package.py cover the whole.
Slow tests (subprocesses, installs, training) are marked ``slow``: ``pytest -m "not slow"``
skips them while developing; CI runs everything."""

import numpy as np
import pytest

import scara_gym  # noqa: F401  (registers the environments)


@pytest.fixture
def c11_target() -> np.ndarray:
    """The benchmark's target q^ = (2, 2, 0.3) [rad, rad, m]."""
    return np.array([2.0, 2.0, 0.3])
