# Lab notebook, not maintained (lab/README.md): written for one entry of docs/experiments.md, on the code of its day.
"""PD behind the robust shield ("all" ranges) on a condition's episodes: every episode that
collides or does not arrive, with its parameters, and the totals (the experiments log, 2026-12-03).

    python lab/shield_episodes.py random-shifts 100 tuning     # the tuning episodes
    python lab/shield_episodes.py random-shifts 100 3000000000  # episodes from another seed
    python lab/shield_episodes.py random-shifts 30              # the evaluation episodes
"""

import sys
import time

from agents.policies import PDPolicy, run_episode
from scara_gym.benchmark.protocol import get_condition, tuning
from scara_gym.envs.randomization import ParameterRanges, leaf_value
from scara_gym.model.params import DEFAULT_PARAMS
from scara_gym.wrappers import Shield


def main(name: str, episodes: int, which: str | None = None) -> None:
    if which == "tuning":
        condition = tuning(name, episodes)
    else:
        condition = get_condition(name) if which is None else get_condition(name).with_seed(int(which))
    env = condition.make_env("pd")
    shield = Shield(env, PDPolicy(env), robust="all")
    paths = ParameterRanges.preset("all", DEFAULT_PARAMS).ranges
    collisions = misses = 0
    started = time.perf_counter()
    for seed in condition.seeds(episodes):
        result = run_episode(env, shield, seed=seed, options=condition.options(seed))
        collisions += result["collisions"] > 0
        misses += not result["success"]
        if result["collisions"] or not result["success"]:
            params = env.unwrapped.episode_params
            print(f"seed {seed}: collisions {result['collisions']}, success {result['success']},",
                  {path: round(leaf_value(params, path), 4) for path in paths}, flush=True)
    print(f"{name} ({which or 'evaluation'}), {episodes} episodes: {collisions} collisions, {misses} not arrived; "
          f"{(time.perf_counter() - started) / episodes:.1f} s per episode")


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), *sys.argv[3:4])
