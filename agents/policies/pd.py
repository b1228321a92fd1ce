"""The classical baseline: the C11 PD law towards the target, blind to the wall."""

from __future__ import annotations

from agents.policies.base import SetpointPolicy
from scara_gym.envs import OBSERVATION_LAYOUT

Q, TARGET_ERROR = OBSERVATION_LAYOUT["q"], OBSERVATION_LAYOUT["target_error"]


class PDPolicy(SetpointPolicy):
    """The classical baseline: command the target, ignore the wall."""

    name = "pd"

    def setpoint(self, obs):
        return obs[Q] + obs[TARGET_ERROR]
