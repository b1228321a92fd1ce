"""The one evaluation loop: a policy's episode in an environment, summarized (and traced)."""

from __future__ import annotations

import numpy as np

from scara_gym.envs import OBSERVATION_LAYOUT

Q, CURRENTS = OBSERVATION_LAYOUT["q"], OBSERVATION_LAYOUT["current"]
TIP_X, TIP_Y = OBSERVATION_LAYOUT["tip_x"], OBSERVATION_LAYOUT["tip_y"]
WALL_DISTANCE, HEIGHT_MARGIN = OBSERVATION_LAYOUT["wall_distance"], OBSERVATION_LAYOUT["height_margin"]
TRACE_COLUMNS = ("t", "tip_x", "tip_y", "wall_distance", "height_margin", "q3")
"""the columns of a recorded episode's trace"""


def _trace_row(obs) -> tuple:
    return obs[TIP_X], obs[TIP_Y], obs[WALL_DISTANCE], obs[HEIGHT_MARGIN], obs[Q][2]


def run_episode(env, policy, seed: int | None = None, options: dict | None = None, record: bool = False):
    """One episode; returns a summary dict (and the per-step trace if record)."""
    obs, _ = env.reset(seed=seed, options=options)
    policy.reset()
    unwrapped = env.unwrapped
    # measured on the true flat observation: the same for noisy and goal-conditioned envs
    state = unwrapped.task.obs[0]
    total, steps, peak = 0.0, 0, np.zeros(3)
    trace = [(0.0, *_trace_row(state))] if record else None
    info = {}
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += reward
        steps += 1
        peak = np.maximum(peak, np.abs(state[CURRENTS]))
        if record:
            trace.append((info["time"], *_trace_row(state)))
        if terminated or truncated:
            break
    summary = {
        "success": bool(info["is_success"]),
        "collisions": int(info["collisions"]),
        # the located C11 event's instant; a goal env's success at a looser goal_tolerance has
        # none: then the end of the step whose goal test passed
        "reach_time": float(info.get("reach_time", info["time"] if info["is_success"] else np.nan)),
        "energy": float(info["energy"]),
        "peak_current_fraction": float(np.max(peak / unwrapped.params.current_limits)),
        "return": float(total),
        "steps": steps,
    }
    if record:
        summary["trace"] = np.array(trace)  # t, tip_x, tip_y, wall_distance, height_margin, q3
    return summary
