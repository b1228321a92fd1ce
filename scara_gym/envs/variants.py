"""Registered variants of the C11 task: ScaraEnv with other fixed arguments, each with its card.

A variant is the same environment class with other defaults (the arguments its id
registers, ``scara_gym.ENV_VARIANTS``), so everything ScaraEnv does it does, and every
argument can still be given. Its card is ScaraEnv's with its own title and summary, its
defaults in the argument list, and its own version history.
"""

from __future__ import annotations

import inspect
import re

from scara_gym.envs.scara_env import ScaraEnv
from scara_gym.envs.task import ScaraTask
from scara_gym.registration import ENTRY_POINTS, ENV_VARIANTS


def _observation_rows(body: str, defaults: dict) -> str:
    """The observation table with the variant's bounds (randomized ranges widen some)."""
    task = ScaraTask(**defaults)
    low, high = task.obs_low, task.obs_high

    def row(match):
        i = int(match.group(1))
        return f"| {i} | {match.group(2)} | {match.group(3)} | {float(low[i]):g} | {float(high[i]):g} |"

    return re.sub(r"^\| (\d+) \| (\w+) \| ([^|]+?) \| [^|]+ \| [^|]+ \|$", row, body, flags=re.M)


def _card(summary: str, defaults: dict, history: str) -> str:
    base = inspect.getdoc(ScaraEnv)
    body = _observation_rows(base[base.index("## Action space"):base.index("## Version history")], defaults)
    for name, value in defaults.items():
        text = repr(value).replace("'", '"')
        body, found = re.subn(rf"^(- {name} \()[^)]*(\))", lambda m, text=text: m.group(1) + text + m.group(2), body,
                              flags=re.M)
        assert found == 1, name
    return f"{inspect.cleandoc(summary)}\n\n{body}## Version history\n\n{inspect.cleandoc(history)}\n"


def _signature(defaults: dict) -> inspect.Signature:
    signature = inspect.signature(ScaraEnv.__init__)
    return signature.replace(parameters=[
        p.replace(default=defaults[p.name]) if p.name in defaults else p for p in signature.parameters.values()])


class _Variant(ScaraEnv):
    env_id: str

    def __init_subclass__(cls, summary: str = "", history: str = "", **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        cls.defaults = dict(ENV_VARIANTS[cls.env_id])
        cls.__doc__ = _card(summary, cls.defaults, history)

        def __init__(self, **kwargs) -> None:
            ScaraEnv.__init__(self, **{**cls.defaults, **kwargs})

        __init__.__signature__ = _signature(cls.defaults)
        __init__.__doc__ = f"ScaraEnv's arguments, with the defaults of {cls.env_id}."
        cls.__init__ = __init__


class ScaraRandomPhysicsEnv(_Variant, summary="""
    Scara-C11-RandomPhysics-v1: the C11 task with the robot's physics drawn per episode.

    The point-to-point move of Scara-C11-v2 (same wall, target, spaces, reward and
    integration) with the load mass, the link masses and each motor's resistance, torque
    constant and current limit drawn uniformly per reset from the "physics" preset of
    ``scara_gym.envs.randomization`` (see the starting state below), the drawn values in the
    reset info. A policy must reach the target fast on robots it has not seen: the setting
    of domain randomization for sim-to-real transfer.
    """, history="""
    - v1: ``randomize_params="physics"`` on the latest id's integration (Scara-C11-v2:
      ``exact_switches=True``, ``rtol=1e-7``, ``atol=1e-9``); the class defaults.
    - v0: first release: ``randomize_params="physics"`` on Scara-C11-v1's physics,
      ``exact_switches=True``, ``rtol=1e-6``, ``atol=1e-8``.
    """):
    env_id = "Scara-C11-RandomPhysics-v1"


class ScaraRandomWallEnv(_Variant, summary="""
    Scara-C11-RandomWall-v1: the C11 task with the wall's position and height drawn per episode.

    The point-to-point move of Scara-C11-v2 (same robot, target, spaces, reward and
    integration) with the wall's plane x_obs drawn from 0.35 +- 0.04 m and its height h_obs
    from 0.15 +- 0.03 m per reset (the "wall" preset of ``scara_gym.envs.randomization``),
    the drawn values in the reset info and the wall features of the observation measured
    from the episode's wall. With the C11 target the task stays solvable: the target tip
    lies beyond the critical band and the target height above the wall for every draw.
    """, history="""
    - v1: ``randomize_params="wall"`` on the latest id's integration (Scara-C11-v2:
      ``exact_switches=True``, ``rtol=1e-7``, ``atol=1e-9``); the class defaults.
    - v0: first release: ``randomize_params="wall"`` on Scara-C11-v1's physics,
      ``exact_switches=True``, ``rtol=1e-6``, ``atol=1e-8``.
    """):
    env_id = "Scara-C11-RandomWall-v1"


from scara_gym.envs.goal import ScaraGoalEnv  # noqa: E402  (its card is its own: a Dict observation)

_CLASSES = {f"{cls.__module__}:{cls.__name__}": cls for cls in (ScaraRandomPhysicsEnv, ScaraRandomWallEnv, ScaraGoalEnv)}
VARIANT_CLASSES = {env_id: _CLASSES[ENTRY_POINTS[env_id]] for env_id in ENV_VARIANTS}
"""Registered variant id -> its class, every version of a variant one class whose defaults are its
latest version's (a test checks every id of ENV_VARIANTS has one)."""
