"""The Gymnasium environments: a task object, the compiled step, and thin adapters over them.

- `config`: `EnvConfig`, every environment's one configuration;
- `task`: `ScaraTask` (records, episodes, info from an EnvConfig),
  `RewardWeights`, the observation layout and the set-point <-> action mapping;
- `core`: the compiled per-robot step;
- `randomization`: parameters drawn per episode (`ParameterRanges`);
- `sim_to_real`: observation noise, actuation delay, action rate limit;
- `variants`, `goal`: the cards of the registered
  variants (randomized physics and wall: ScaraEnv with other arguments) and the goal-conditioned task;
- `scara_env`: `ScaraEnv`, the env of every registered id;
- `vector`: `ScaraVectorEnv`, the native vector environment;
- `rendering`: the matplotlib renderer.
"""

from scara_gym.envs.config import EnvConfig
from scara_gym.envs.randomization import PRESETS as RANDOMIZATION_PRESETS, ParameterRanges
from scara_gym.envs.scara_env import ScaraEnv
from scara_gym.envs.task import (
    OBSERVATION_LAYOUT,
    OBSERVATION_NAMES,
    REWARD_TERMS,
    RewardWeights,
    ScaraTask,
)

__all__ = ["EnvConfig", "OBSERVATION_LAYOUT", "OBSERVATION_NAMES", "RANDOMIZATION_PRESETS", "REWARD_TERMS", "ParameterRanges",
           "RewardWeights", "ScaraEnv", "ScaraTask"]
