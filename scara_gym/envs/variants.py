"""The cards of the registered variants of the C11 task: ScaraEnv with other registered arguments.

A variant is no class of its own: its id registers `ScaraEnv` with
other arguments (an `EnvConfig` value,
``scara_gym.registration.ENV_VARIANTS``), so everything ScaraEnv does it does, and every
argument can still be given. Its card (`card_of`) is ScaraEnv's with its own title,
summary, observation bounds and argument defaults, and its own version history. The goal
ids' card is `ScaraGoalEnv`'s (a Dict observation).
"""

from __future__ import annotations

import importlib
import inspect

from scara_gym.envs.config import EnvConfig
from scara_gym.envs.scara_env import card
from scara_gym.registration import ENTRY_POINTS, ENV_KWARGS

_RANDOM_PHYSICS = card("""
    Scara-C11-RandomPhysics-v1: the C11 task with the robot's physics drawn per episode.

    The point-to-point move of Scara-C11-v2 (same wall, target, spaces, reward and
    integration) with the load mass, the link masses and each motor's resistance, torque
    constant and current limit drawn uniformly per reset from the "physics" preset of
    ``scara_gym.envs.randomization`` (see the starting state below), the drawn values in the
    reset info. A policy must reach the target fast on robots it has not seen: the setting
    of domain randomization for sim-to-real transfer.
    """, EnvConfig(**ENV_KWARGS["Scara-C11-RandomPhysics-v1"]), """
    - v1: ``randomize_params="physics"`` on the latest id's integration (Scara-C11-v2:
      ``exact_switches=True``, ``rtol=1e-7``, ``atol=1e-9``).
    - v0: first release: ``randomize_params="physics"`` on Scara-C11-v1's physics,
      ``exact_switches=True``, ``rtol=1e-6``, ``atol=1e-8``.
    """)

_RANDOM_WALL = card("""
    Scara-C11-RandomWall-v1: the C11 task with the wall's position and height drawn per episode.

    The point-to-point move of Scara-C11-v2 (same robot, target, spaces, reward and
    integration) with the wall's plane x_obs drawn from 0.35 +- 0.04 m and its height h_obs
    from 0.15 +- 0.03 m per reset (the "wall" preset of ``scara_gym.envs.randomization``),
    the drawn values in the reset info and the wall features of the observation measured
    from the episode's wall. With the C11 target the task stays solvable: the target tip
    lies beyond the critical band and the target height above the wall for every draw.
    """, EnvConfig(**ENV_KWARGS["Scara-C11-RandomWall-v1"]), """
    - v1: ``randomize_params="wall"`` on the latest id's integration (Scara-C11-v2:
      ``exact_switches=True``, ``rtol=1e-7``, ``atol=1e-9``).
    - v0: first release: ``randomize_params="wall"`` on Scara-C11-v1's physics,
      ``exact_switches=True``, ``rtol=1e-6``, ``atol=1e-8``.
    """)

VARIANT_CARDS = {
    "Scara-C11-RandomPhysics-v0": _RANDOM_PHYSICS, "Scara-C11-RandomPhysics-v1": _RANDOM_PHYSICS,
    "Scara-C11-RandomWall-v0": _RANDOM_WALL, "Scara-C11-RandomWall-v1": _RANDOM_WALL,
}
"""variant id -> its card (every version of a variant one card, its defaults the latest version's)"""


def entry_class(env_id: str) -> type:
    """The class a registered id builds."""
    module, _, name = ENTRY_POINTS.get(env_id, "scara_gym.envs:ScaraEnv").partition(":")
    return getattr(importlib.import_module(module), name)


def card_of(env_id: str) -> str:
    """The card of a registered id: its variant card, else its class's."""
    if env_id in VARIANT_CARDS:
        return inspect.cleandoc(VARIANT_CARDS[env_id])
    return inspect.getdoc(entry_class(env_id))
