"""What every policy is: observation in, action out, for one environment.

A policy is called once per control step with the environment's observation and returns
its action; ``reset()`` starts an episode; ``name`` labels it in tables. Policies that
think in set-points (PD, the heuristic) derive from `SetpointPolicy`, which turns a
set-point into the action of either control mode (the task's ``setpoint_action``).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Policy(Protocol):
    """obs -> action for one environment; reset() at the start of each episode."""

    name: str

    def reset(self) -> None: ...

    def __call__(self, obs: np.ndarray) -> np.ndarray: ...


class SetpointPolicy:
    """A policy that chooses a set-point q^ [rad, rad, m]: in "pd" mode the action commands it,
    in "voltage" mode the policy evaluates the C11 PD law on the observation towards it."""

    name = "policy"

    def __init__(self, env) -> None:
        self.env = env.unwrapped

    def reset(self) -> None:
        pass

    def setpoint(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.env.setpoint_action(obs, self.setpoint(np.asarray(obs, dtype=float)))
