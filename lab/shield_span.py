# Lab notebook, not maintained (lab/README.md): written for one entry of docs/experiments.md, on the code of its day.
"""Assumption D of the robust shield (scara_gym.wrappers.shield): how far robots drawn inside the "all"
ranges leave the span of the shield's models (tip x, tool height) along the rollouts it checks (the
policy's action, then the backup to its set-point), at states along shielded adversarial episodes
(the experiments log, 2026-12-05).

    python lab/shield_span.py 8 24     # 8 episodes, 24 robots drawn per episode
"""

import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from scara_gym.envs.randomization import ParameterRanges
from scara_gym.envs.task import OBSERVATION_LAYOUT, EpisodePlan, ScaraTask
from scara_gym.model.params import DEFAULT_PARAMS
from scara_gym.wrappers import Shield
from scara_gym.wrappers.shield import split_ranges

sys.path.insert(0, str(Path(__file__).parents[2] / "tests" / "agents"))
from test_shield import InterventionSeeker, WallDriver, WallHugger  # noqa: E402

STEPS = 80     # control steps of each rollout compared
EVERY = 5      # a state every this many steps of an episode
TIP_X, HEIGHT = OBSERVATION_LAYOUT["tip_x"], OBSERVATION_LAYOUT["q"].start + 2


def rollouts(task: ScaraTask, params: list, snapshot: dict, action, setpoint) -> np.ndarray:
    """(STEPS, robots, 2): tip x and tool height [m] of each robot of ``task`` with ``params`` from
    ``snapshot``: ``action``, then the backup to ``setpoint``."""
    n = len(params)
    for i, p in enumerate(params):
        task.begin_episode(i, EpisodePlan(task.default_start, snapshot["target"], p, {}))
        task.restore(i, {**snapshot, "params": p})
    out = np.zeros((STEPS, n, 2))
    actions = np.tile(np.asarray(action, dtype=float), (n, 1))
    for k in range(STEPS):
        task.step_robots(np.ones(n, dtype=bool), np.ascontiguousarray(actions), parallel=False)
        out[k, :, 0], out[k, :, 1] = task.obs[:, TIP_X], task.obs[:, HEIGHT]
        actions = np.ascontiguousarray(np.broadcast_to(task.setpoint_action(task.obs.astype(float), setpoint), (n, 3)))
    return out


def main(episodes: int, robots: int) -> None:
    ranges = ParameterRanges.preset("all", DEFAULT_PARAMS)
    physics = ParameterRanges(split_ranges(ranges)[1])
    rng = np.random.default_rng(53)
    worst, states, started = np.zeros(2), 0, time.perf_counter()
    for episode in range(episodes):
        drawn = ranges.draw(rng) if episode % 2 == 0 else {p: b[rng.integers(2)] for p, b in ranges.ranges.items()}
        kwargs = {"control_mode": ("pd", "voltage")[episode % 2], "action_delay": episode % 3,
                  "action_rate_limit": (None, 20.0)[episode // 2 % 2]}
        env = gym.make("Scara-C11-v1", params=DEFAULT_PARAMS.replace(drawn), **kwargs)
        adversary = (WallHugger, WallDriver, InterventionSeeker)[episode % 3](env, episode)
        shield = Shield(env, adversary, robust="all")
        adversary.shield = shield
        between = [shield.params.replace(physics.draw(rng)).replace(shield.zone) for _ in range(robots)]
        check = ScaraTask(env.unwrapped.config, num_robots=robots)
        obs, _ = env.reset(seed=episode)
        for step in range(150):
            action = adversary(obs)
            snapshot = env.unwrapped.snapshot()
            if step % EVERY == 0 and shield.certify(snapshot, action):  # the rollouts the shield accepts
                setpoint = shield.backup_setpoint(snapshot)
                models = rollouts(shield.model_task, shield.model_params, snapshot, action, setpoint)
                others = rollouts(check, between, snapshot, action, setpoint)
                low, high = models.min(axis=1)[:, None], models.max(axis=1)[:, None]
                beyond = np.maximum(0.0, np.maximum(others - high, low - others))  # outside the models' span
                worst = np.maximum(worst, [beyond[..., 0].max(), beyond[..., 1][others[..., 1] < low[..., 1]].max(
                    initial=0.0)])
                states += 1
            action, replaced = shield.filter(env, 0, action)
            shield.interventions += replaced
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        print(f"episode {episode} ({adversary.name}, {kwargs}): {states} certified states so far, the farthest "
              f"outside the models' span: tip x {1e3 * worst[0]:.2f} mm, tool height (below) {1e3 * worst[1]:.2f} mm",
              flush=True)
    print(f"{states} certified states, {robots} robots each: {1e3 * worst[0]:.2f} mm in x, {1e3 * worst[1]:.2f} mm "
          f"below in height; {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]))
