"""The seed paper's ``dec`` obstacle heuristic as a policy, and its smallest safe trigger distance.

It acts through the environment's action interface only (observation in, action
out), for either control mode:

- "pd" mode: the action is the PD set-point; the environment's PD law makes voltages.
- "voltage" mode: the policy evaluates the same C11 PD law on the observation, once per
  control step, and commands U / limit, where limit is the voltage permitted at that
  instant (widened while the observation says critical): ``env.pd_action``.

How the seed's model change maps onto actions. The paper slows joints 1-2 by
replacing q1' = v1, q2' = v2 with q' = dec v while the tip is critical, which freezes
the arm instantly. No controller can do that to a real arm; the closest a policy can
do is to stop commanding motion: at the trigger it freezes the set-points of axes 1-2
at the positions it sees, so the PD law brakes the arm (with the widened voltage the
environment grants near the wall), while axis 3 keeps climbing to its target. Because
braking takes distance, the trigger distance ``critical_distance`` is a parameter of
the policy (the paper's d_crit = 0.02 m is too short for a real stop; see
``smallest_safe_distance``). ``dec`` sets how much of the remaining way to the target
the frozen set-point still moves per second (dec = 0: frozen). Release:

- "continue" (the seed's continuous variant): target again as soon as q3 >= h_obs;
- "restart" (its restart variant): target again once q3 >= h_obs and the arm has come
  to rest (|q1'|, |q2'| < rest_rate), the policy's counterpart of resetting the rates.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from agents.policies.base import SetpointPolicy
from scara_gym.benchmark.episodes import run_episode
from scara_gym.benchmark.protocol import ENV_ID
from scara_gym.envs import OBSERVATION_LAYOUT
from scara_gym.model.checks import UserError
from scara_gym.wrappers.shield import hold_and_climb

Q, RATES, TARGET_ERROR = (OBSERVATION_LAYOUT[name] for name in ("q", "rate", "target_error"))
WALL_DISTANCE, HEIGHT_MARGIN = OBSERVATION_LAYOUT["wall_distance"], OBSERVATION_LAYOUT["height_margin"]


class DecHeuristic(SetpointPolicy):
    """The seed's obstacle rule as a policy (module docstring): freeze, climb, release."""

    def __init__(self, env, variant: str = "continue", critical_distance: float = 0.1,
                 dec: float = 0.0, rest_rate: float = 0.05) -> None:
        super().__init__(env)
        if variant not in ("continue", "restart"):
            raise UserError(f"variant must be 'continue' or 'restart', got {variant!r}")
        if not (np.isfinite(critical_distance) and critical_distance > 0):
            raise UserError(f"critical_distance must be a finite number > 0 [m], got {critical_distance!r}")
        if not (np.isfinite(dec) and 0 <= dec <= 1):
            raise UserError(f"dec must be in [0, 1], got {dec!r}")
        if not (np.isfinite(rest_rate) and rest_rate > 0):
            raise UserError(f"rest_rate must be a finite number > 0 [rad/s], got {rest_rate!r}")
        self.variant = variant
        self.critical_distance = float(critical_distance)
        self.dec = float(dec)
        self.rest_rate = float(rest_rate)
        self.name = f"dec-{variant} (d={critical_distance:g} m)"
        self.reset()

    def reset(self) -> None:
        self.phase = "approach"
        self.frozen = None

    def setpoint(self, obs):
        target = obs[Q] + obs[TARGET_ERROR]
        below = obs[HEIGHT_MARGIN] < 0
        if self.phase == "approach" and below and abs(obs[WALL_DISTANCE]) < self.critical_distance:
            self.phase = "frozen"
            self.frozen = obs[Q].copy()
        if self.phase == "frozen":
            rested = np.all(np.abs(obs[RATES][:2]) < self.rest_rate)
            if not below and (self.variant == "continue" or rested):
                self.phase = "released"
            else:
                self.frozen[:2] += self.dec * self.env.control_dt * (target[:2] - self.frozen[:2])
                return hold_and_climb(self.frozen, target)
        return target


def smallest_safe_distance(variant: str = "continue", env_kwargs: dict | None = None,
                           low: float = 0.0, high: float = 0.4, tolerance: float = 1e-3, env=None, seed: int = 0,
                           episodes: list[tuple] | None = None):
    """Bisection for the smallest trigger distance at which the heuristic clears the wall
    and reaches the target in the episode of `seed` (of `env`, by default Scara-C11-v0 with
    `env_kwargs`), or in every episode of ``episodes`` ((env, seed, reset options) triples);
    returns (distance, the first episode's summary there)."""
    if episodes is None:
        if env is None:
            env = gym.make(ENV_ID, **(env_kwargs or {}))
        episodes = [(env, seed, None)]

    def safe(distance: float):
        results = []
        for env_, seed_, options in episodes:
            result = run_episode(env_, DecHeuristic(env_, variant, critical_distance=distance), seed=seed_,
                                 options=options)
            results.append(result)
            if result["collisions"] or not result["success"]:
                return False, results[0]
        return True, results[0]

    ok, result = safe(high)
    if not ok:
        raise RuntimeError(f"the {variant} heuristic collides even at critical_distance = {high} m")
    best = (high, result)
    while high - low > tolerance:
        middle = 0.5 * (low + high)
        ok, result = safe(middle)
        if ok:
            high, best = middle, (middle, result)
        else:
            low = middle
    return best
