"""The registered Gymnasium ids: each id's constructor arguments (its card's version history),
registered with Gymnasium when `scara_gym` is imported.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

ENV_VERSIONS = {
    # v0: the 0.1 integration, switches seen at the ends of integration steps
    "Scara-C11-v0": {"rtol": 1e-5, "atol": 1e-6, "exact_switches": False},
    # v1: every mode switch located inside the steps; within the accuracy targets except the
    # currents right after the critical switch's voltage jump ("voltage" mode)
    "Scara-C11-v1": {"rtol": 1e-6, "atol": 1e-8, "exact_switches": True},
    # v2: v1 at rtol 1e-7 / atol 1e-9, which also keeps the currents after the voltage jump at the
    # critical switch within the targets (1.45x v1's right-hand sides; README, "Accuracy")
    "Scara-C11-v2": {"rtol": 1e-7, "atol": 1e-9, "exact_switches": True},
}
"""Registered id -> the integration arguments it fixes (the card's version history)."""
LATEST_ENV_ID = "Scara-C11-v2"
"""The one id for every use: the exact physics within every accuracy target at its tolerances.
The classes' defaults are its integration arguments (``LATEST_INTEGRATION``); agents train,
tune, evaluate and compare on it. The older ids stay registered and frozen (their behaviour
digests are tested), for results made on them."""
LATEST_INTEGRATION = dict(ENV_VERSIONS[LATEST_ENV_ID])
"""The integration arguments of the latest id: the default of every environment class."""
_V1_INTEGRATION = ENV_VERSIONS["Scara-C11-v1"]
ENV_VARIANTS = {
    # the C11 task with parameters drawn per episode (scara_gym.envs.randomization)
    "Scara-C11-RandomPhysics-v0": {**_V1_INTEGRATION, "randomize_params": "physics"},
    "Scara-C11-RandomWall-v0": {**_V1_INTEGRATION, "randomize_params": "wall"},
    # the goal-conditioned task (Dict observations, compute_reward for HER), goals drawn per episode
    "Scara-C11-Goal-v0": {**_V1_INTEGRATION, "randomize_target": True},
    # v1 of each: the same task on the latest id's integration
    "Scara-C11-RandomPhysics-v1": {**LATEST_INTEGRATION, "randomize_params": "physics"},
    "Scara-C11-RandomWall-v1": {**LATEST_INTEGRATION, "randomize_params": "wall"},
    "Scara-C11-Goal-v1": {**LATEST_INTEGRATION, "randomize_target": True},
}
"""Registered variant id -> the arguments it fixes (each variant's card: scara_gym.envs.variants)."""
GOAL_ENV_IDS = ("Scara-C11-Goal-v0", "Scara-C11-Goal-v1")
"""The ids with the goal API (Dict observations, compute_reward): SB3 trains them with HER."""
ENV_KWARGS = {**ENV_VERSIONS, **ENV_VARIANTS}
"""Every registered id -> the constructor arguments it registers (the vector env gets them too)."""
ENV_IDS = tuple(ENV_KWARGS)
"""Every environment id this package registers."""
LATEST_IDS = ("Scara-C11-v2", "Scara-C11-RandomPhysics-v1", "Scara-C11-RandomWall-v1", "Scara-C11-Goal-v1")
"""The newest version of each family: every other id is frozen (Gymnasium calls it out of date)."""
ENTRY_POINTS = {env_id: "scara_gym.envs.goal:ScaraGoalEnv" for env_id in GOAL_ENV_IDS}
"""Id -> its class (module:name) where it is not scara_gym.envs:ScaraEnv (the variants are ScaraEnv
with other arguments; their cards: scara_gym.envs.variants)."""
_VECTOR_ENTRY_POINTS = {env_id: "scara_gym.envs.goal:make_goal_vector_env" for env_id in GOAL_ENV_IDS}


def register_all() -> None:
    """Register every id of ENV_KWARGS with Gymnasium (the ones not registered yet)."""
    for env_id, kwargs in ENV_KWARGS.items():
        if env_id not in registry:
            # 300 steps of the default 0.01 s control step: the 3 s time limit
            register(id=env_id, entry_point=ENTRY_POINTS.get(env_id, "scara_gym.envs:ScaraEnv"),
                     max_episode_steps=300,
                     vector_entry_point=_VECTOR_ENTRY_POINTS.get(env_id, "scara_gym.envs.factory:make_vector_env"),
                     kwargs=dict(kwargs))
