"""Every policy parameter the comparison uses, chosen once by a written rule on the tuning set.

The rule for the ``dec`` heuristic's trigger distance: the smallest distance (bisection on
[0, 0.4] m to ``TOLERANCE``) at which the heuristic reaches the target without a collision in
the nominal C11 episode and in the first ``TUNING_EPISODES`` episodes of c11-starts' tuning set
(``scara_gym.benchmark.protocol.tuning``: its start distribution on tuning seeds), "pd" mode,
on the protocol's id (``protocol.ENV_ID``). The comparison lists the heuristic at that distance and at ``MARGIN`` times
it, in every condition: never re-tuned on a condition it is scored on.

The shield's margins are its documented defaults (scara_gym.wrappers.Shield), not tuned here.
"""

from __future__ import annotations

from agents.policies import smallest_safe_distance
from scara_gym.benchmark.protocol import CONDITIONS, tuning

TUNING_EPISODES = 20
"""episodes of c11-starts' tuning set the heuristic's distance must clear (besides the C11 episode)"""
TOLERANCE = 5e-4  # [m] of the bisection
MARGIN = 1.2
"""the heuristic's second row: its tuned distance times this"""


def tuning_episodes(episodes: int = TUNING_EPISODES) -> list[tuple]:
    """The tuning set as (condition, seed) pairs: the C11 episode and c11-starts' tuning episodes."""
    starts = tuning("c11-starts", episodes)
    return [(CONDITIONS["c11"], CONDITIONS["c11"].seed)] + [(starts, s) for s in starts.seeds()]


def tune_heuristic(variant: str, episodes: int = TUNING_EPISODES, tolerance: float = TOLERANCE) -> dict:
    """{"distance", "margin_distance", "rule", "episodes"}: the heuristic's tuned trigger distance
    by the module's rule (RuntimeError where no distance up to 0.4 m clears the tuning set)."""
    pairs = tuning_episodes(episodes)
    envs = {}
    plan = []
    for condition, seed in pairs:
        env = envs.setdefault(condition.name, condition.make_env("pd"))
        plan.append((env, seed, condition.options(seed)))
    distance, _ = smallest_safe_distance(variant, tolerance=tolerance, episodes=plan)
    return {"distance": distance, "margin_distance": MARGIN * distance, "episodes": len(plan),
            "rule": f"smallest trigger distance (bisection to {tolerance:g} m) that reaches the target without a "
                    f"collision in the C11 episode and {episodes} episodes of c11-starts' tuning seeds; "
                    f"margin row: {MARGIN:g} x"}
