"""Shared fixtures. Tests mirror the package: tests/model (physics, integrator), tests/envs (task,
compiled step, environments), tests/benchmark (the seed paper's tasks, the command line),
tests/integrations, tests/agents; tests/test_behaviour.py and tests/test_package.py cover the whole.
Slow tests (subprocesses, installs, training) are marked ``slow``: ``pytest -m "not slow"``
skips them while developing; CI runs everything."""

import os
import shutil
import tempfile

import numpy as np
import pytest

import scara_gym  # noqa: F401  (registers the environments)
from agents import files

# the runs the tests train record their manifests in a trust store of their own, not the user's, and
# the runs they publish extend a copy of the published runs' list of manifests (results/runs), not the list
_TRUST = tempfile.mkdtemp(prefix="scara-trust-")
os.environ["SCARA_GYM_TRUST_STORE"] = os.path.join(_TRUST, "trusted_manifests")
os.environ["SCARA_GYM_PUBLISHED_MANIFESTS"] = shutil.copy(files.CHECKOUT_RUNS / files.PUBLISHED_LIST,
                                                          os.path.join(_TRUST, "published"))
os.environ.pop("SCARA_GYM_PUBLISHED_RUNS", None)
os.environ.pop("SCARA_GYM_TRUST", None)


@pytest.fixture
def c11_target() -> np.ndarray:
    """The benchmark's target q^ = (2, 2, 0.3) [rad, rad, m]."""
    return np.array([2.0, 2.0, 0.3])
