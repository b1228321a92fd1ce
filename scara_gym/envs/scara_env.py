"""Scara-C11-v0: the C11 point-to-point move with the wall of task c in the way."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from scara_gym import layout as L
from scara_gym.dynamics import tip_position
from scara_gym.envs.core import (
    N_OBS, N_RESULT, N_SPEC, R_CLIPPED, R_COLLISIONS, R_REACH_TIME, R_REACHED, R_REWARD, R_STATUS,
    R_DISTANCE, R_TERMS, R_TIP, R_VOLTAGE, REWARD_TERMS, S_ATOL, S_CENTER, S_DT, S_HALF, S_OBSTACLE, S_PD,
    S_RTOL, S_TIME_LIMIT, S_WEIGHTS, robot_step, start_episode,
)
from scara_gym.params import DEFAULT_PARAMS, ScaraParams
from scara_gym.simulation import Simulator, check_state

CONTROL_MODES = ("pd", "voltage")
COLLISION_MODES = ("terminate", "penalty")

# PD set-point range the action [-1, 1] spans [rad, rad, m]
SETPOINT_LOW = np.array([-math.pi, -math.pi, 0.0])
SETPOINT_HIGH = np.array([math.pi, math.pi, 0.4])
# randomize_target draws q^ uniformly from this box [rad, rad, m]; see the card
TARGET_LOW = np.array([1.5, 1.5, 0.2])
TARGET_HIGH = np.array([2.5, 2.5, 0.35])
TARGET_CLEARANCE = 0.02  # [m] a drawn target tip keeps this much beyond the critical band
ANGLE_BOUND = 6 * math.pi   # [rad] observation bound of q1, q2 (clipped beyond)
HEIGHT_BOUND = 1.0          # [m]
ANGLE_RATE_BOUND = 20.0     # [rad/s]
HEIGHT_RATE_BOUND = 2.0     # [m/s]


@dataclass(frozen=True)
class RewardWeights:
    """Weights of the named reward terms (all >= 0; the sign is in the term)."""

    progress: float = 10.0
    """per unit reduction of the scaled target distance ||(q - q^) / (1 rad, 1 rad, 0.1 m)||"""
    time: float = 10.0
    """per second of simulated time (a cost)"""
    energy: float = 0.001
    """per joule of electrical energy drawn, int sum U_i I_i dt (a cost)"""
    collision: float = 50.0
    """per collision with the wall (a cost)"""
    success: float = 10.0
    """once, when all |q_i - q^_i| < acc"""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                    math.isfinite(value) and value >= 0):
                raise ValueError(f"reward_weights.{f.name} must be a finite number >= 0, got {value!r}")

    def to_array(self) -> np.ndarray:
        return np.array([getattr(self, name) for name in REWARD_TERMS], dtype=float)


def draw_target(rng: np.random.Generator, start: np.ndarray, params: ScaraParams, p: np.ndarray,
                obstacle: bool) -> np.ndarray:
    """A target from the documented region that needs the wall passed and is reachable above it."""
    obs = params.obstacle
    x_start, _, _ = tip_position(start[0], start[1], start[2], p)
    start_side = 1.0 if x_start >= obs.x_position else -1.0
    for _ in range(1000):
        target = rng.uniform(TARGET_LOW, TARGET_HIGH)
        if not obstacle:
            return target
        x_tip, _, _ = tip_position(target[0], target[1], target[2], p)
        beyond = (x_tip - obs.x_position) * start_side < -(obs.critical_distance + TARGET_CLEARANCE)
        if beyond and target[2] >= obs.height + TARGET_CLEARANCE:
            return target
    raise RuntimeError("randomize_target: no target in the documented region passes the wall "
                       "rules with these parameters")


def check_actions(action, shape: tuple[int, ...]) -> np.ndarray:
    """Finite float64 actions of the given shape (C-contiguous; not yet clipped: the compiled
    step clips them to [-1, 1] and counts the clipped components)."""
    try:
        a = np.ascontiguousarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"action must be numbers in [-1, 1] of shape {shape}, got {action!r}") from None
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape}, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"action must be finite (allowed range [-1, 1]), got {a.tolist()}")
    return a


class ScaraEnv(gym.Env):
    """The ARGESIM C11 SCARA robot: reach the target fast without hitting the wall.

    The benchmark's point-to-point move from q = (0, 0, 0) to q^ = (2, 2, 0.3) with the
    wall of task c in the way: a plane at x = x_obs (0.35 m) of height h_obs (0.15 m).
    The tool tip must not cross the plane while q3 < h_obs. The episode succeeds at the
    first instant all |q_i - q^_i| < acc = 0.001 (located inside the control step). The
    physics is the exact C11 model (DC motors with current limits, saturated PD law),
    integrated with located events between control steps.

    ## Action space

    ``Box(-1, 1, (3,), float32)``; components outside [-1, 1] are clipped and counted in
    ``info["clipped_actions"]``.

    | control_mode | index | meaning | unit |
    |---|---|---|---|
    | pd | 0 | PD set-point q^1 = a0 * pi | rad |
    | pd | 1 | PD set-point q^2 = a1 * pi | rad |
    | pd | 2 | PD set-point q^3 = 0.2 + 0.2 a2 | m |
    | voltage | 0 | armature voltage U1 = a0 * limit1 | V |
    | voltage | 1 | armature voltage U2 = a1 * limit2 | V |
    | voltage | 2 | armature voltage U3 = a2 * limit3 | V |

    In ``"pd"`` mode the C11 PD law U_i = sat(P_i (q^_i - q_i) - D_i q_i', +-limit_i)
    turns the set-point into voltages. limit_i is Umax_i = (100, 75, 90) V, widened to
    Umax_wide_i = (200, 150, 180) V while the tip is critical (|x_tip - x_obs| < d_crit
    and q3 < h_obs, the seed's rule of task c; only with ``obstacle=True``). So in
    ``"voltage"`` mode the action range always spans the voltage permitted at that
    instant, and the PD law saturates at the widened bound there. The set-point and the
    voltages are held over the control step; the limit switches at the located instant
    the tip becomes critical.

    ## Observation space

    ``Box(low, high, (18,), float32)``, physical units; values beyond the bounds are
    clipped (q1, q2 beyond +-6 pi rad cannot happen within 3 s at the motors' speeds).
    The wall features are 0 with ``obstacle=False``.

    | index | name | unit | low | high |
    |---|---|---|---|---|
    | 0 | q1 | rad | -18.8496 | 18.8496 |
    | 1 | q2 | rad | -18.8496 | 18.8496 |
    | 2 | q3 | m | -1 | 1 |
    | 3 | q1_rate | rad/s | -20 | 20 |
    | 4 | q2_rate | rad/s | -20 | 20 |
    | 5 | q3_rate | m/s | -2 | 2 |
    | 6 | current1 | A | -6.64 | 6.64 |
    | 7 | current2 | A | -2.771 | 2.771 |
    | 8 | current3 | A | -1.732 | 1.732 |
    | 9 | target_error1 | rad | -37.6991 | 37.6991 |
    | 10 | target_error2 | rad | -37.6991 | 37.6991 |
    | 11 | target_error3 | m | -2 | 2 |
    | 12 | tip_x | m | -0.7 | 0.7 |
    | 13 | tip_y | m | -0.7 | 0.7 |
    | 14 | wall_distance | m | -1.05 | 1.05 |
    | 15 | height_margin | m | -1.15 | 1.15 |
    | 16 | critical | 1 | 0 | 1 |
    | 17 | time_left | 1 | 0 | 1 |

    target_error = q^ - q; wall_distance = x_tip - x_obs (signed); height_margin =
    q3 - h_obs; critical = 1 while the widened voltage applies; time_left =
    max(0, 1 - t / time_limit). The bounds of the currents, tip, wall distance and
    height margin follow the parameters (the table shows the defaults).

    ## Reward

    A sum of named terms, each a weight of ``reward_weights`` times:

    - progress: d(q_before) - d(q_after), d(q) = ||(q - q^) / (1 rad, 1 rad, 0.1 m)||
    - time: -(duration of the step) [s]
    - energy: -(electrical energy drawn in the step) [J]
    - collision: -(number of collisions in the step)
    - success: +1 on reaching the target

    The weighted terms are in ``info["reward_terms"]``; they sum to the reward.

    ## Starting state

    q = ``start`` (default (0, 0, 0)), rates and currents zero. The target is
    ``target`` (default (2, 2, 0.3)) or, with ``randomize_target=True``, drawn uniformly
    from q^1, q^2 in [1.5, 2.5] rad, q^3 in [0.2, 0.35] m, redrawn until its tip lies
    beyond the wall by d_crit + 0.02 m and q^3 >= h_obs + 0.02 m (with the defaults
    every draw does): every such target needs the wall passed and is reachable above it.
    ``reset(options={"target": ..., "start": ...})`` overrides either for one episode.

    ## Episode end

    - terminated: the target is reached (``info["is_success"]``), or a collision with
      ``collision="terminate"``; both are located inside the step, which ends there.
    - truncated: only by the time limit, ``max_episode_steps=300`` (3 s) as registered.

    A collision is the tool tip crossing the plane x = x_obs while q3 < h_obs, located
    inside the step (a tip that crosses between two control steps is caught). With
    ``collision="penalty"`` the arm passes through and the episode goes on.
    ``info["cost"]`` is 1 for a step in which the tip entered the wall (the wall is a
    plane: entering it is crossing it below h_obs), else 0.

    ## Info

    reward_terms, is_success, cost, collision (this step), collisions (episode total),
    critical, time (s), energy (J, episode total),
    current_limited (3 bools: held at its limit at the end of the step), voltage (V, at
    the end of the step), clipped_actions (components clipped this step), target; and
    reach_time (s, the located instant) on the step that reaches the target.

    ## Arguments

    - control_mode ("pd"): "pd" or "voltage", see the action space.
    - obstacle (True): the wall of task c and the widened voltage near it.
    - collision ("terminate"): "terminate" or "penalty".
    - target (None): q^ [rad, rad, m]; None: the C11 target (2, 2, 0.3).
    - start (None): q(0) [rad, rad, m]; None: the C11 start (0, 0, 0).
    - randomize_target (False): draw q^ per episode, see the starting state.
    - reward_weights (None): a RewardWeights or a dict of its fields.
    - control_dt (0.01): control step [s]; render_fps = 1 / control_dt.
    - time_limit (3.0): horizon of the time_left feature [s]; keep
      max_episode_steps = time_limit / control_dt when changing either.
    - params (None): a ScaraParams, or a dict of dotted-path overrides of the C11
      defaults, e.g. {"arm.load_mass": 1.0, "obstacle.height": 0.2}.
    - rtol (1e-05): relative integration tolerance inside the step (scipy's meaning).
    - atol (1e-06): absolute integration tolerance inside the step. With these defaults
      the states stay within 1e-7 of a tight-tolerance reference (the tests allow 1e-4).
    - render_mode (None): "rgb_array" (headless) or "human" (needs a display).

    ## Version history

    - v0: first release.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 100}

    def __init__(self, control_mode: str = "pd", obstacle: bool = True, collision: str = "terminate",
                 target=None, start=None, randomize_target: bool = False,
                 reward_weights: RewardWeights | dict | None = None, control_dt: float = 0.01,
                 time_limit: float = 3.0, params: ScaraParams | dict | None = None,
                 rtol: float = 1e-5, atol: float = 1e-6, render_mode: str | None = None) -> None:
        if control_mode not in CONTROL_MODES:
            raise ValueError(f"control_mode must be one of {CONTROL_MODES}, got {control_mode!r}")
        if collision not in COLLISION_MODES:
            raise ValueError(f"collision must be one of {COLLISION_MODES}, got {collision!r}")
        if not isinstance(obstacle, (bool, np.bool_)):
            raise TypeError(f"obstacle must be True or False, got {obstacle!r}")
        for name, value in (("control_dt", control_dt), ("time_limit", time_limit)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                    math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0 [s], got {value!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, "
                             f"got {render_mode!r}")
        if params is None:
            params = DEFAULT_PARAMS
        elif isinstance(params, dict):
            params = DEFAULT_PARAMS.replace(params)
        elif not isinstance(params, ScaraParams):
            raise TypeError(f"params must be a ScaraParams or a dict of overrides, got {type(params).__name__}")
        if reward_weights is None:
            reward_weights = RewardWeights()
        elif isinstance(reward_weights, dict):
            unknown = set(reward_weights) - {f.name for f in fields(RewardWeights)}
            if unknown:
                raise ValueError(f"reward_weights has unknown terms {sorted(unknown)}; "
                                 f"allowed: {[f.name for f in fields(RewardWeights)]}")
            reward_weights = RewardWeights(**reward_weights)
        elif not isinstance(reward_weights, RewardWeights):
            raise TypeError("reward_weights must be a RewardWeights or a dict")

        self.params = params
        self.control_mode = control_mode
        self.obstacle = bool(obstacle)
        self.collision_mode = collision
        self.randomize_target = bool(randomize_target)
        self.reward_weights = reward_weights
        self.control_dt = float(control_dt)
        self.time_limit = float(time_limit)
        self.render_mode = render_mode
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / self.control_dt}
        self.default_target = self._check_target(target if target is not None else params.task.target, "target")
        self.default_start = check_state("start", start if start is not None else params.task.start, 3)

        stops = ("target", "collision") if (self.obstacle and collision == "terminate") else ("target",)
        self.sim = Simulator(
            params, control=control_mode, critical="switch" if self.obstacle else "off",
            widen=self.obstacle, wall=self.obstacle, stop=stops, rtol=rtol, atol=atol,
            max_step=self.control_dt, record=0, max_events=256)
        self._p = self.sim.p  # the kernel reads the target from here
        self._weights = reward_weights.to_array()
        self._result = np.zeros(N_RESULT)
        self._obs = np.zeros(N_OBS, dtype=np.float32)
        self._no_record = (np.empty(0), np.empty((0, L.N_STATE)), np.empty((0, 3)))

        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        low, high = self._observation_bounds()
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self._setpoint_center = 0.5 * (SETPOINT_HIGH + SETPOINT_LOW)
        self._setpoint_half = 0.5 * (SETPOINT_HIGH - SETPOINT_LOW)
        self._spec = self._compiled_spec()
        self._bounds = np.stack([low, high])
        self._needs_reset = True
        self._renderer = None
        if render_mode == "human":
            from scara_gym.envs.rendering import require_display
            require_display()

    def _compiled_spec(self) -> np.ndarray:
        """The constants of the compiled step (layout S_* of scara_gym.envs.core)."""
        spec = np.zeros(N_SPEC)
        spec[S_DT] = self.control_dt
        spec[S_RTOL] = self.sim.rtol
        spec[S_ATOL] = self.sim.atol
        spec[S_TIME_LIMIT] = self.time_limit
        spec[S_OBSTACLE] = float(self.obstacle)
        spec[S_PD] = float(self.control_mode == "pd")
        spec[S_WEIGHTS:S_WEIGHTS + 5] = self._weights
        spec[S_CENTER:S_CENTER + 3] = self._setpoint_center
        spec[S_HALF:S_HALF + 3] = self._setpoint_half
        return spec

    # -- spaces ------------------------------------------------------------------------
    observation_names = (
        "q1", "q2", "q3", "q1_rate", "q2_rate", "q3_rate", "current1", "current2", "current3",
        "target_error1", "target_error2", "target_error3", "tip_x", "tip_y", "wall_distance",
        "height_margin", "critical", "time_left")

    def _observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        reach = self.params.arm.reach
        obs = self.params.obstacle
        wall = reach + abs(obs.x_position)
        margin = HEIGHT_BOUND + abs(obs.height)
        high = np.array([
            ANGLE_BOUND, ANGLE_BOUND, HEIGHT_BOUND, ANGLE_RATE_BOUND, ANGLE_RATE_BOUND, HEIGHT_RATE_BOUND,
            *self.params.current_limits, 2 * ANGLE_BOUND, 2 * ANGLE_BOUND, 2 * HEIGHT_BOUND,
            reach, reach, wall, margin, 1.0, 1.0])
        low = -high
        low[16:] = 0.0
        return low.astype(np.float32), high.astype(np.float32)

    def setpoint_to_action(self, setpoint) -> np.ndarray:
        """The "pd" action (float64, unclipped) that commands the set-point q^ [rad, rad, m]."""
        return (check_state("setpoint", setpoint, 3) - self._setpoint_center) / self._setpoint_half

    def action_to_setpoint(self, action) -> np.ndarray:
        return self._setpoint_center + self._setpoint_half * np.asarray(action, dtype=float)

    # -- validation --------------------------------------------------------------------
    def _check_target(self, target, name: str) -> np.ndarray:
        target = check_state(name, target, 3)
        inside = np.all((target >= SETPOINT_LOW) & (target <= SETPOINT_HIGH))
        if self.control_mode == "pd" and not inside:
            raise ValueError(f"{name} must lie in the set-point range q1, q2 in [-pi, pi] rad, "
                             f"q3 in [0, 0.4] m of the 'pd' mode, got {target.tolist()}")
        return target

    # -- API ---------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        start, target = self.episode_start(self.np_random, options)
        self.target = target.copy()
        self._p[L.TARGET:L.TARGET + 3] = target
        x0 = np.zeros(L.N_STATE)
        x0[:3] = start
        self._command = target.copy() if self.control_mode == "pd" else np.zeros(3)
        sim = self.sim
        sim.x[:] = x0
        sim.t = 0.0
        sim.command = self._command
        self._distance = start_episode(
            sim.x, self._p, self._command, sim.config, sim.modes, sim.step_state, sim.counters,
            self._spec, self._bounds, self._obs, self._result)
        self._reach_time = None
        self._collisions = 0
        self._needs_reset = False
        self._trace = [self._tip()]
        if self.render_mode == "human":
            self.render()
        return self._obs.copy(), {"target": self.target.copy(), "start": start.copy()}

    def episode_start(self, rng: np.random.Generator, options: dict | None) -> tuple[np.ndarray, np.ndarray]:
        """(start, target) of a new episode from the reset options and the episode RNG."""
        options = {} if options is None else dict(options)
        unknown = set(options) - {"target", "start"}
        if unknown:
            raise ValueError(f"unknown reset options {sorted(unknown)}; allowed: 'target', 'start'")
        start = check_state("options['start']", options["start"], 3) if "start" in options else self.default_start
        if "target" in options:
            target = self._check_target(options["target"], "options['target']")
        elif self.randomize_target:
            target = draw_target(rng, start, self.params, self._p, self.obstacle)
        else:
            target = self.default_target
        if np.max(np.abs(start - target)) < self.params.task.accuracy:
            raise ValueError(f"start {start.tolist()} is already within acc of the target {target.tolist()}")
        return start.copy(), target.copy()

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("the episode has ended (or never started): call reset() before step()")
        if not (type(action) is np.ndarray and action.shape == (3,) and action.dtype.char in "fd"
                and action.flags.c_contiguous):
            action = check_actions(action, (3,))  # converts, or raises naming the problem
        sim = self.sim
        result = self._result
        t = robot_step(action, sim.x, sim.t, self._p, self._command, sim.config, sim.modes,
                       sim.step_state, self._spec, self._bounds, self._distance, sim.ev_t,
                       sim.ev_code, sim.ev_axis, sim.counters, result, self._obs)
        if math.isnan(t):  # a non-finite action, rejected before anything changed
            check_actions(action, (3,))  # raises naming it
        sim.t = t
        values = result.tolist()
        if values[R_STATUS] < 0:
            raise RuntimeError(f"integration failed ({sim.status_name(int(values[R_STATUS]))}) "
                               f"at t = {t:.6f} s")
        collisions = int(values[R_COLLISIONS])
        reached = values[R_REACHED] == 1.0
        if reached:
            self._reach_time = values[R_REACH_TIME]
        self._collisions += collisions
        self._distance = values[R_DISTANCE]
        terminated = reached or (collisions > 0 and self.collision_mode == "terminate")
        self._needs_reset = terminated
        if self.render_mode is not None:
            self._trace.append((values[R_TIP], values[R_TIP + 1]))
        modes = sim.modes
        info = {
            "reward_terms": dict(zip(REWARD_TERMS, values[R_TERMS:R_TERMS + 5])),
            "is_success": reached,
            "cost": 1.0 if collisions else 0.0,
            "collision": collisions > 0,
            "collisions": self._collisions,
            "critical": bool(modes[L.M_CRITICAL]),
            "time": t,
            "energy": sim.x[L.ENERGY].item(),
            "current_limited": modes[:3] != 0,
            "voltage": np.array(values[R_VOLTAGE:R_VOLTAGE + 3]),
            "clipped_actions": int(values[R_CLIPPED]),
            "target": self.target.copy(),
        }
        if reached:
            info["reach_time"] = self._reach_time
        if self.render_mode == "human":
            self.render()
        return self._obs.copy(), values[R_REWARD], terminated, False, info

    # -- helpers -----------------------------------------------------------------------
    def _tip(self) -> tuple[float, float]:
        return self._result[R_TIP], self._result[R_TIP + 1]

    # -- rendering ---------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' "
                            "or 'human' to gym.make")
            return None
        if self._renderer is None:
            from scara_gym.envs.rendering import ScaraRenderer
            self._renderer = ScaraRenderer(self.params, human=self.render_mode == "human")
        x = self.sim.x
        frame = self._renderer.draw(
            q=x[:3], target=self.target, trace=self._trace, obstacle=self.obstacle,
            critical=self.sim.critical, time=self.sim.t, collisions=self._collisions)
        return frame if self.render_mode == "rgb_array" else None

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_renderer"] = None
        return state
