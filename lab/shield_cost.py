# Lab notebook, not maintained (lab/README.md): written for one entry of docs/experiments.md, on the code of its day.
"""The robust shield's cost per decision (us), the zone's (this tree) beside an earlier commit's, in one
sitting: PD on random-shifts' first evaluation episodes and the wall-hugger on issue 53's robot A from
c11-starts' first starts,
each episode behind both shields in turn (the experiments log, 2026-12-05).

    python lab/shield_cost.py dfe4f9e 5     # today's shield against the one before issue 53
"""

import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from agents.policies import PDPolicy
from scara_gym.benchmark.protocol import get_condition
from scara_gym.model.params import DEFAULT_PARAMS
from scara_gym.wrappers import shield as current

sys.path.insert(0, str(Path(__file__).parents[2] / "tests" / "agents"))
from test_shield import ROBOT_A, WallHugger  # noqa: E402


def module_at(commit: str):
    """scara_gym/wrappers/shield.py as it was at ``commit``, imported under another name."""
    source = subprocess.run(["git", "show", f"{commit}:scara_gym/wrappers/shield.py"], check=True,
                            capture_output=True, text=True).stdout
    path = Path(tempfile.mkdtemp()) / "shield_then.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("shield_then", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def timed_episode(env, shield_class, policy_class, seed: int, options) -> tuple[list[float], int]:
    """Each decision's time [s] (the shield's filter) over one episode, and its collisions."""
    shield = shield_class(env, None, robust="all")
    policy = policy_class(env)
    obs, _ = env.reset(seed=seed, options=options)
    policy.reset()
    times = []
    for _ in range(300):
        action = policy(obs)
        started = time.perf_counter()
        action, _ = shield.filter(env, 0, action)
        times.append(time.perf_counter() - started)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    return times, int(info["collisions"])


def main(commit: str, episodes: int) -> None:
    then = module_at(commit)
    shifts = get_condition("random-shifts")
    cases = [("pd, random-shifts", shifts.make_env("pd"), PDPolicy, s, shifts.options(s)) for s in shifts.seeds(episodes)]
    robot, starts = gym.make("Scara-C11-v1", params=DEFAULT_PARAMS.replace(ROBOT_A)), get_condition("c11-starts")
    cases += [("wall hugger, robot A, c11-starts", robot, lambda env: WallHugger(env, 0), s, starts.options(s))
              for s in starts.seeds(episodes)]
    totals = {name: {"then": [], "now": [], "collisions then": 0, "collisions now": 0} for name, *_ in cases}
    for name, env, policy, seed, options in cases:
        for label, module in (("then", then), ("now", current)):
            times, collisions = timed_episode(env, module.Shield, policy, seed, options)
            totals[name][label] += times
            totals[name][f"collisions {label}"] += collisions
    for name, row in totals.items():
        print(f"{name}, {episodes} episodes: " + "; ".join(
            f"{label} ({commit if label == 'then' else 'this tree'}) {1e6 * np.mean(row[label]):,.0f} us mean, "
            f"{1e6 * np.median(row[label]):,.0f} us median over {len(row[label])} decisions, "
            f"{row[f'collisions {label}']} collisions" for label in ("then", "now")))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
