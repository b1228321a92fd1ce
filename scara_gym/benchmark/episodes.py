"""The one evaluation loop: a policy's episode in an environment, summarized (and traced), and
a policy's episodes as per-episode arrays.

A policy is a callable obs -> action; its ``reset()`` is called before each episode where it has one
(``agents.policies.Policy``).

Success is scored at several precisions. At the C11 band (the task's accuracy, 1e-3 rad for q1, q2
and 1e-3 m for q3) it is the environment's own located event: ``info["is_success"]`` and its instant
``info["reach_time"]`` (the episode ends there). At the looser bands ``BANDS`` (1e-2 and 5e-2, the
same units) the environment locates nothing, and the time to a band b is measured here, on the true
state (not the observation, which may be noisy): the first instant among the episode's start (t = 0)
and the control steps' ends (every 10 ms) at which every |q_i - q^_i| < b; where the episode
reaches the C11 band, the time to b is at most its located instant (a looser band is never
reported later than the C11 success of the same episode: the state passes through b on its way
to 1e-3, between two step ends). A band is reached ("success" at it) where that time exists; as
the C11 success, it counts where the tool passes through the band whatever follows. So, where
all are reached: time to 5e-2 <= time to 1e-2 <= time to 1e-3.
"""

from __future__ import annotations

import numpy as np

from scara_gym.envs import OBSERVATION_LAYOUT
from scara_gym.model.checks import UserError
from scara_gym.model.records import Q as STATE_Q

Q, CURRENTS = OBSERVATION_LAYOUT["q"], OBSERVATION_LAYOUT["current"]
TIP_X, TIP_Y = OBSERVATION_LAYOUT["tip_x"], OBSERVATION_LAYOUT["tip_y"]
WALL_DISTANCE, HEIGHT_MARGIN = OBSERVATION_LAYOUT["wall_distance"], OBSERVATION_LAYOUT["height_margin"]
TRACE_COLUMNS = ("t", "tip_x", "tip_y", "wall_distance", "height_margin", "q3")
"""the columns of a recorded episode's trace"""
C11_BAND = "1e-3"
"""the name of the C11 band: the environment's own success (``success``, ``reach_time``)"""
BANDS = {"1e-2": 1e-2, "5e-2": 5e-2}
"""the looser success bands (name -> b; rad for q1, q2, m for q3) scored beside the C11 band: an
episode's arrays hold ``success_NAME`` and ``reach_time_NAME`` for each (module docstring)"""
BAND_NAMES = (C11_BAND, *BANDS)
"""every band scored, tightest first"""


def band_keys(name: str) -> tuple[str, str]:
    """The per-episode arrays (success, time to the band) of the band named ``name`` (BAND_NAMES):
    the C11 band's are the environment's own ``success`` and ``reach_time``.
    """
    return ("success", "reach_time") if name == C11_BAND else (f"success_{name}", f"reach_time_{name}")


def _target_error(env) -> float:
    """max_i |q_i - q^_i| of the (unwrapped single) env's robot's true state."""
    return float(np.max(np.abs(env.state[STATE_Q:STATE_Q + 3] - env.target)))


def band_times(errors, times, located: float | None = None) -> dict[str, float]:
    """Band name -> time to the band (NaN: not reached) of an episode whose target errors
    max_i |q_i - q^_i| are ``errors`` at the instants ``times`` (the start and every step's end,
    in order); located: the instant of the environment's located C11 success, where the episode
    has one (a band's time is at most it).
    """
    errors, times = np.asarray(errors, dtype=float), np.asarray(times, dtype=float)
    out = {}
    for name, band in BANDS.items():
        inside = np.flatnonzero(errors < band)
        t = float(times[inside[0]]) if inside.size else np.nan
        out[name] = t if located is None else float(np.fmin(t, located))
    return out


def _trace_row(obs) -> tuple:
    return obs[TIP_X], obs[TIP_Y], obs[WALL_DISTANCE], obs[HEIGHT_MARGIN], obs[Q][2]


def run_episode(env, policy, seed: int | None = None, options: dict | None = None, record: bool = False):
    """One episode; returns a summary dict (and the per-step trace if record)."""
    obs, _ = env.reset(seed=seed, options=options)
    if callable(getattr(policy, "reset", None)):  # a plain function has no episode state to reset
        policy.reset()
    unwrapped = env.unwrapped
    # measured on the true flat observation: the same for noisy and goal-conditioned envs
    state = unwrapped.noise_free_observation()
    total, steps, peak = 0.0, 0, np.zeros(3)
    trace = [(0.0, *_trace_row(state))] if record else None
    errors, times = [_target_error(unwrapped)], [0.0]  # at the start and every step's end (band_times)
    info = {}
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += reward
        steps += 1
        state = unwrapped.noise_free_observation()
        peak = np.maximum(peak, np.abs(state[CURRENTS]))
        if record:
            trace.append((info["time"], *_trace_row(state)))
        errors.append(_target_error(unwrapped))
        times.append(info["time"])
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
        # the looser bands' times (module docstring), at most the located C11 instant where there is one
        **{f"reach_time_{name}": t for name, t in band_times(errors, times, info.get("reach_time")).items()},
    }
    if record:
        summary["trace"] = np.array(trace)  # t, tip_x, tip_y, wall_distance, height_margin, q3
    return summary


SUMMARY_KEYS = ("success", "collisions", "reach_time", "energy", "steps", *(f"reach_time_{name}" for name in BANDS))
"""what makes two episodes' summaries the same episode (run_episodes' shortcut)"""


def _same_episode(a: dict, b: dict) -> bool:
    return all(a[key] == b[key] or (key.startswith("reach_time") and np.isnan(a[key]) and np.isnan(b[key]))
               for key in SUMMARY_KEYS)


def run_episodes(env, policy, seeds: list[int], options: list[dict | None] | None = None, identical: bool = False,
                 record: int = 1) -> dict:
    """Per-episode arrays of ``policy`` over the episodes of ``seeds`` (with the reset
    ``options`` of each, where given), with the traces of the first ``record`` episodes
    ("trace": the first one's; "traces": all of them) and the seeds ("seeds"); the looser bands'
    ``success_NAME`` and ``reach_time_NAME`` (NaN where not reached) for each name of BANDS.
    identical: the episodes draw nothing (fixed start, target and parameters, no noise) and the
    policy is deterministic, so that every episode is the first one: then the first two are run
    and, where they are the same, the first stands for all (else every episode runs).
    """
    seeds = [int(s) for s in seeds]
    options = list(options) if options is not None else [None] * len(seeds)
    if len(options) != len(seeds):
        raise UserError(f"options must have one entry per seed ({len(seeds)}), got {len(options)}")

    def run(i: int) -> dict:
        return run_episode(env, policy, seed=seeds[i], options=options[i], record=i < record)

    results = [run(i) for i in range(min(len(seeds), 2))]
    if identical and len(seeds) > 2 and _same_episode(*results):
        results += [results[0]] * (len(seeds) - 2)
    else:
        results += [run(i) for i in range(len(results), len(seeds))]
    reach = np.array([r["reach_time"] if r["success"] else np.nan for r in results])
    bands = {}
    for name in BANDS:
        success, reach_time = band_keys(name)
        bands[reach_time] = np.array([r[reach_time] for r in results])
        bands[success] = np.isfinite(bands[reach_time])
    return {"success": np.array([r["success"] for r in results]),
            "collisions": np.array([r["collisions"] > 0 for r in results]),
            "collision_counts": np.array([r["collisions"] for r in results]),
            "reach_time": reach, "energy": np.array([r["energy"] for r in results]),
            "peak_current_fraction": np.array([r["peak_current_fraction"] for r in results]),
            "return": np.array([r["return"] for r in results]),
            "seeds": np.array(seeds, dtype=np.int64),
            "trace": results[0].get("trace"), "traces": [r["trace"] for r in results[:record]], **bands}
