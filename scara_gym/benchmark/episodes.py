"""The one evaluation loop: a policy's episode in an environment, summarized (and traced), and
a policy's episodes as per-episode arrays.

A policy is a callable obs -> action; its ``reset()`` is called before each episode where it has one
(``agents.policies.Policy``).
"""

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
    if callable(getattr(policy, "reset", None)):  # a plain function has no episode state to reset
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


SUMMARY_KEYS = ("success", "collisions", "reach_time", "energy", "steps")
"""what makes two episodes' summaries the same episode (run_episodes' shortcut)"""


def _same_episode(a: dict, b: dict) -> bool:
    return all(a[key] == b[key] or (key == "reach_time" and np.isnan(a[key]) and np.isnan(b[key]))
               for key in SUMMARY_KEYS)


def run_episodes(env, policy, seeds: list[int], options: list[dict | None] | None = None, identical: bool = False,
                 record: int = 1) -> dict:
    """Per-episode arrays of ``policy`` over the episodes of ``seeds`` (with the reset
    ``options`` of each, where given), with the traces of the first ``record`` episodes
    ("trace": the first one's; "traces": all of them) and the seeds ("seeds").
    identical: the episodes draw nothing (fixed start, target and parameters, no noise) and the
    policy is deterministic, so that every episode is the first one: then the first two are run
    and, where they are the same, the first stands for all (else every episode runs)."""
    seeds = [int(s) for s in seeds]
    options = list(options) if options is not None else [None] * len(seeds)
    if len(options) != len(seeds):
        raise ValueError(f"options must have one entry per seed ({len(seeds)}), got {len(options)}")

    def run(i: int) -> dict:
        return run_episode(env, policy, seed=seeds[i], options=options[i], record=i < record)

    results = [run(i) for i in range(min(len(seeds), 2))]
    if identical and len(seeds) > 2 and _same_episode(*results):
        results += [results[0]] * (len(seeds) - 2)
    else:
        results += [run(i) for i in range(len(results), len(seeds))]
    reach = np.array([r["reach_time"] if r["success"] else np.nan for r in results])
    return {"success": np.array([r["success"] for r in results]),
            "collisions": np.array([r["collisions"] > 0 for r in results]),
            "collision_counts": np.array([r["collisions"] for r in results]),
            "reach_time": reach, "energy": np.array([r["energy"] for r in results]),
            "peak_current_fraction": np.array([r["peak_current_fraction"] for r in results]),
            "return": np.array([r["return"] for r in results]),
            "seeds": np.array(seeds, dtype=np.int64),
            "trace": results[0].get("trace"), "traces": [r["trace"] for r in results[:record]]}
