"""The C11 task: one owner of the configuration, the compiled records and the episode logic.

`ScaraTask` validates the environment's arguments, holds the record arrays the
compiled step (`scara_gym.envs.core`) works on for N robots, draws targets,
resets robots and turns step outcomes into termination and info. The single
environment is a ``ScaraTask`` with one robot, the vector environment one with N; both
are thin Gymnasium adapters over it. No gymnasium import here: spaces are the adapters'.

Public layouts: ``OBSERVATION_NAMES`` (one name per observation entry, the card's
table) and ``OBSERVATION_LAYOUT`` (field name -> slice or index). The task object itself is
internal (an env's ``_task``): agents and wrappers use the envs' state surface
(``scara_gym.envs.surface``), e.g. ``env.unwrapped.setpoint_to_action``.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from scara_gym.envs.config import FIELDS, EnvConfig, make_config
from scara_gym.envs.core import (
    INFO_FIELDS,
    N_INFO,
    N_OBS,
    OBSERVATION,
    OUTCOME,
    REWARD_TERMS,
    TASK,
    begin_robot,
    pack_info,
    pd_actions,
    restore_robot,
    step_robot,
    step_robots,
    step_robots_serial,
)
from scara_gym.envs.randomization import ParameterRanges, check_overrides, within_bounds
from scara_gym.envs.sim_to_real import Actuator, SimToReal, add_noise, sense
from scara_gym.model import checks, records as R
from scara_gym.model.dynamics import tip_position
from scara_gym.model.params import DEFAULT_PARAMS, ScaraParams, resolve_params
from scara_gym.model.simulator import CONTROLS, SimulationError, check_state, check_tolerance, failure_message

CONTROL_MODES = ("pd", "voltage")
CONTROL_DT_RANGE = (1e-4, 1.0)  # [s]
TIME_LIMIT_MAX = 1e4            # [s]
MAX_ROBOTS = 2**24
DEFAULT_DEC = DEFAULT_PARAMS.obstacle.dec
COLLISION_MODES = ("terminate", "penalty")

# PD set-point range the action [-1, 1] spans [rad, rad, m]
SETPOINT_LOW = np.array([-math.pi, -math.pi, 0.0])
SETPOINT_HIGH = np.array([math.pi, math.pi, 0.4])
# "pd" set-point = SETPOINT_CENTER + SETPOINT_HALF * action
SETPOINT_CENTER = 0.5 * (SETPOINT_HIGH + SETPOINT_LOW)
SETPOINT_HALF = 0.5 * (SETPOINT_HIGH - SETPOINT_LOW)
# randomize_target draws q^ uniformly from this box [rad, rad, m]; see the card
# starts and targets must lie in the joint range [rad, rad, m]: the set-point range
JOINT_LOW, JOINT_HIGH = SETPOINT_LOW, SETPOINT_HIGH
JOINT_RANGE_TEXT = "q1, q2 in [-pi, pi] rad and q3 in [0, 0.4] m"
TARGET_LOW = np.array([1.5, 1.5, 0.2])
TARGET_HIGH = np.array([2.5, 2.5, 0.35])
TARGET_CLEARANCE = 0.02  # [m] a drawn target tip keeps this much beyond the critical band
START_REGION = (np.array([-0.05, -0.05, 0.0]), np.array([0.05, 0.05, 0.05]))
"""randomize_start=True draws the start as start + uniform offsets in this box [rad, rad, m]"""
MAX_START_OFFSET = 1.0  # [rad, rad, m] a start region's half-width at most
ANGLE_BOUND = 6 * math.pi   # [rad] observation bound of q1, q2 (clipped beyond)
HEIGHT_BOUND = 1.0          # [m]
ANGLE_RATE_BOUND = 20.0     # [rad/s]
HEIGHT_RATE_BOUND = 2.0     # [m/s]
EVENT_LOG_SIZE = 256        # events one robot can log in one control step

# numba's workqueue threading layer (the one left where OpenMP and TBB are missing, e.g.
# macOS wheels) aborts the process when two threads run parallel code at once; one
# parallel step at a time is safe under every layer and costs nothing, since each step
# already uses all of numba's threads
PARALLEL_LOCK = threading.Lock()

OBSERVATION_LAYOUT = {
    name: (slice(offset, offset + dtype.shape[0]) if dtype.shape else offset)
    for name, (dtype, offset) in ((n, (OBSERVATION[n], OBSERVATION.fields[n][1] // 4))
                                  for n in OBSERVATION.names)
}
"""Observation field -> slice (vectors) or index (scalars) of the flat observation."""
OBSERVATION_NAMES = (
    "q1", "q2", "q3", "q1_rate", "q2_rate", "q3_rate", "current1", "current2", "current3",
    "target_error1", "target_error2", "target_error3", "tip_x", "tip_y", "wall_distance",
    "height_margin", "critical", "time_left")
"""One name per observation entry (the card's table)."""
assert len(OBSERVATION_NAMES) == N_OBS
OBSERVATION_UNITS = ("rad", "rad", "m", "rad/s", "rad/s", "m/s", "A", "A", "A", "rad", "rad", "m", "m", "m", "m", "m",
                     "1", "1")
"""The unit of each observation entry (the card's table)."""


def observation_table(task: ScaraTask) -> str:
    """The card's observation table: index, name, unit and the bounds of ``task``'s observation space."""
    rows = ["| index | name | unit | low | high |", "|---|---|---|---|---|"]
    for i, (name, unit) in enumerate(zip(OBSERVATION_NAMES, OBSERVATION_UNITS)):
        rows.append(f"| {i} | {name} | {unit} | {float(task.obs_low[i]):g} | {float(task.obs_high[i]):g} |")
    return "\n".join(rows)


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
            object.__setattr__(self, f.name, checks.real(f"reward_weights.{f.name}", getattr(self, f.name), 0.0))


def check_actions(action, shape: tuple[int, ...]) -> np.ndarray:
    """Finite float64 actions of the given shape (C-contiguous; not yet clipped: the compiled
    step clips them to [-1, 1] and counts the clipped components). Real numbers only: a
    complex, boolean, text or object action is an error, not a cast.
    """
    try:
        return checks.real_array("action", action, shape, range_text="values in [-1, 1] (beyond: clipped)")
    except TypeError as error:  # one exception type for every bad action
        raise ValueError(str(error)) from None


def vector_seeds(seed, num_envs: int) -> list[int | None]:
    """A vector env's reset seed per robot: None, an integer s (robot i gets s + i) or a list of
    num_envs integers or None.
    """
    text = f"seed must be None, an integer >= 0 or a list of {num_envs} such seeds or None"
    if seed is None or checks.is_real(seed) or isinstance(seed, (bool, np.bool_)):
        first = checks.seed("seed", seed)
        return [None if first is None else first + i for i in range(num_envs)]
    if not isinstance(seed, (list, tuple, np.ndarray)) or len(seed) != num_envs:
        raise ValueError(f"{text}, got {seed!r}")
    return [checks.seed(f"seed[{i}]", s) for i, s in enumerate(seed)]


def draw_target(rng: np.random.Generator, start: np.ndarray, params: ScaraParams, obstacle: bool) -> np.ndarray:
    """A target from the documented region that needs the wall passed and is reachable above it."""
    obs = params.obstacle
    p = params.to_record()
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


class EpisodePlan(NamedTuple):
    """A checked episode start: what `ScaraTask.begin_episode` applies to one robot."""

    start: np.ndarray
    target: np.ndarray
    params: ScaraParams
    """the episode's parameters (the nominal ones unless randomized or overridden)"""
    varied: dict
    """dotted path -> value of every parameter drawn or overridden for this episode"""


RESET_OPTIONS = ("target", "start", "params")


def draw_start(rng: np.random.Generator, start: np.ndarray, region: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """A start drawn as ``start`` + uniform offsets in ``region`` (low, high), inside the joint range."""
    return np.clip(np.asarray(start, dtype=float) + rng.uniform(*region), JOINT_LOW, JOINT_HIGH)


def _start_region(value) -> tuple[np.ndarray, np.ndarray] | None:
    """randomize_start: False/None (off), True (START_REGION) or (low, high) offsets [rad, rad, m]."""
    if value is None or value is False:
        return None
    if value is True:
        return START_REGION
    text = ("randomize_start must be False, True or (low, high): two 3-vectors of offsets [rad, rad, m] "
            f"from the start with low <= high, each within +-{MAX_START_OFFSET}")
    try:
        low = checks.real_array("randomize_start[0]", value[0], (3,), unit="rad, rad, m")
        high = checks.real_array("randomize_start[1]", value[1], (3,), unit="rad, rad, m")
    except (TypeError, ValueError, IndexError, KeyError):
        raise ValueError(f"{text}, got {value!r}") from None
    if len(value) != 2 or np.any(low > high) or np.any(np.abs(low) > MAX_START_OFFSET) \
            or np.any(np.abs(high) > MAX_START_OFFSET):
        raise ValueError(f"{text}, got {value!r}")
    return low, high


def _reward_weights(reward_weights) -> RewardWeights:
    if reward_weights is None:
        return RewardWeights()
    if isinstance(reward_weights, RewardWeights):
        return reward_weights
    names = [f.name for f in fields(RewardWeights)]
    if isinstance(reward_weights, Mapping):
        unknown = sorted(map(str, set(reward_weights) - set(names)))
        if unknown:
            raise ValueError(f"reward_weights has unknown terms {unknown}; allowed: {names}")
        return RewardWeights(**reward_weights)
    raise TypeError(f"reward_weights must be a RewardWeights or a dict with keys among {names}, "
                    f"got {reward_weights!r}")


INFO_SCALARS = INFO_FIELDS.index("hold1")
"""INFO_FIELDS' scalar entries, before the hold, voltage and target vectors"""


class ScaraTask:
    """Scara-C11 for ``num_robots`` robots, configured by an `EnvConfig`
    (``config``, default ``EnvConfig()``) with keyword overrides of its fields.

    The environments' engine, not a public API of its own (an env holds it as ``_task``): the
    envs declare what agents and wrappers may use (snapshots, the set-point maps, the targets,
    per-robot observations) in `scara_gym.envs.surface`.
    Its compiled records are ``step_config`` (the step's configuration), ``constants`` (the
    task's constants), and per robot ``robots``, ``robot_params``, ``outcomes`` and ``obs``.
    """

    def __init__(self, config: EnvConfig | None = None, num_robots: int = 1, **overrides) -> None:
        self.env_config = config = make_config(config, overrides)
        """the task's configuration (a model of this task, the shield's, is built from it)"""
        (control_mode, obstacle, collision, target, start, randomize_target, reward_weights, control_dt, time_limit,
         params, rtol, atol, exact_switches, randomize_params, observation_noise, action_delay, action_rate_limit,
         sensor_noise, randomize_start, tolerance_weights) = (getattr(config, name) for name in FIELDS)
        self.control_mode = checks.choice("control_mode", control_mode, CONTROL_MODES)
        self.obstacle = checks.flag("obstacle", obstacle)
        self.collision_mode = checks.choice("collision", collision, COLLISION_MODES)
        self.randomize_target = checks.flag("randomize_target", randomize_target)
        self.control_dt = checks.real("control_dt", control_dt, *CONTROL_DT_RANGE, unit="s")
        self.time_limit = checks.real("time_limit", time_limit, self.control_dt, TIME_LIMIT_MAX,
                                      unit="s, at least control_dt")
        self.params = resolve_params(params)
        if self.params.obstacle.dec != DEFAULT_DEC:
            raise ValueError(
                f"params: obstacle.dec = {self.params.obstacle.dec!r} has no effect in the environment, "
                f"where the agent decides how to pass the wall; the seed's dec rule lives in "
                f"scara_gym.obstacle_avoidance(dec=...) (the model) and agents.policies.DecHeuristic "
                f"(a policy for this environment). Leave obstacle.dec at {DEFAULT_DEC:g}")
        self.reward_weights = _reward_weights(reward_weights)
        self.randomization = ParameterRanges.from_argument(randomize_params, self.params)
        # the observation bounds hold every episode's parameters: built around the range ends
        self.bound_params = self.randomization.extreme(self.params) if self.randomization else self.params
        self.rtol = check_tolerance("rtol", rtol)
        self.atol = check_tolerance("atol", atol)
        self.exact_switches = checks.flag("exact_switches", exact_switches)
        self.tolerance_weights = checks.tolerance_weights(tolerance_weights, R.STATE_GROUPS)
        num_robots = checks.integer("num_robots", num_robots, 1, MAX_ROBOTS)
        self.default_target = self.check_joints(target if target is not None else self.params.task.target, "target")
        self.default_start = self.check_joints(start if start is not None else self.params.task.start, "start")
        self.start_region = _start_region(randomize_start)
        """(low, high) offsets from the start drawn per episode, or None (the start fixed)"""
        self.setpoint_center = SETPOINT_CENTER
        self.setpoint_half = SETPOINT_HALF
        self.obs_low, self.obs_high = self._observation_bounds()
        self.num_robots = n = num_robots
        self.sim_to_real = SimToReal.from_arguments(observation_noise, action_delay, action_rate_limit,
                                                    self.control_dt, OBSERVATION_LAYOUT, OBSERVATION_NAMES,
                                                    sensor_noise)
        self.actuator = Actuator(self.sim_to_real, n) if self.sim_to_real.shapes_actions else None
        """the delay line and rate limit between the agent's and the applied actions, where any"""

        # the compiled step's records: shared configuration and constants, per-robot state
        self.step_config = np.zeros(1, dtype=R.CONFIG)
        config = self.step_config[0]
        config["control"] = CONTROLS[control_mode]
        config["critical_rule"] = R.CRIT_SWITCH if self.obstacle else R.CRIT_OFF
        config["widen"] = config["wall"] = self.obstacle
        stops = R.STOP_TARGET | (R.STOP_COLLISION if (self.obstacle and collision == "terminate") else 0)
        config["stops"] = stops
        config["max_steps"] = 2_000_000
        config["rtol"], config["atol"] = self.rtol, self.atol
        config["tolerance_weights"] = self.tolerance_weights
        config["exact_switches"] = self.exact_switches
        self.constants = np.zeros(1, dtype=TASK)
        constants = self.constants[0]
        constants["control_dt"], constants["time_limit"] = self.control_dt, self.time_limit
        constants["obstacle"], constants["pd"] = self.obstacle, control_mode == "pd"
        for term in REWARD_TERMS:
            constants[f"{term}_weight"] = getattr(self.reward_weights, term)
        constants["setpoint_center"], constants["setpoint_half"] = self.setpoint_center, self.setpoint_half
        constants["obs_low"], constants["obs_high"] = self.obs_low, self.obs_high
        self.nominal_record = self.params.to_record()
        self.robot_params = np.repeat(np.array([self.nominal_record], dtype=R.PARAMS), n)
        self.episode_params = [self.params] * n
        """each robot's parameters in its current episode"""
        self.robots = np.zeros(n, dtype=R.ROBOT)
        self.log = np.zeros((n, EVENT_LOG_SIZE), dtype=R.EVENT)
        self.outcomes = np.zeros(n, dtype=OUTCOME)
        self.obs = np.zeros((n, N_OBS), dtype=np.float32)
        self._info_buffer = np.zeros(N_INFO)

    # -- layouts and mappings ------------------------------------------------------------
    def _observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        reach = self.bound_params.arm.reach
        obs = self.bound_params.obstacle
        wall = reach + abs(obs.x_position)
        margin = HEIGHT_BOUND + abs(obs.height)
        high = np.array([
            ANGLE_BOUND, ANGLE_BOUND, HEIGHT_BOUND, ANGLE_RATE_BOUND, ANGLE_RATE_BOUND, HEIGHT_RATE_BOUND,
            *self.bound_params.current_limits, 2 * ANGLE_BOUND, 2 * ANGLE_BOUND, 2 * HEIGHT_BOUND,
            reach, reach, wall, margin, 1.0, 1.0])
        low = -high
        low[OBSERVATION_LAYOUT["critical"]] = low[OBSERVATION_LAYOUT["time_left"]] = 0.0
        return low.astype(np.float32), high.astype(np.float32)

    def setpoint_to_action(self, setpoint) -> np.ndarray:
        """The "pd" action (float64, unclipped) that commands the set-point q^ [rad, rad, m]."""
        return self._pd_actions(check_state("setpoint", setpoint, 3))

    def _pd_actions(self, setpoints) -> np.ndarray:
        """The "pd" actions (unclipped, unchecked) of set-points, batches too: the mapping's one formula."""
        return (np.asarray(setpoints, dtype=float) - self.setpoint_center) / self.setpoint_half

    def action_to_setpoint(self, action) -> np.ndarray:
        """The "pd" set-point q^ [rad, rad, m] an action commands (batches too)."""
        return self.setpoint_center + self.setpoint_half * np.asarray(action, dtype=float)

    def pd_action(self, obs, setpoint, robot: int | None = None) -> np.ndarray:
        """The "voltage"-mode action that applies the C11 PD law to a set-point q^ [rad, rad, m]
        on an observation: U / limit, with the widened limit where the observation says
        critical (what the environment's "pd" mode does, evaluated once per control step).
        Batches: obs (n, 18) and setpoint (n, 3) or (3,) give (n, 3); one obs gives (3,).
        robot: whose parameters (default: robot i's for row i of a batch over all robots, else
        the first robot's).
        """
        single = np.ndim(obs) == 1
        obs = np.atleast_2d(np.asarray(obs, dtype=np.float64))
        setpoints = np.ascontiguousarray(np.broadcast_to(np.asarray(setpoint, dtype=np.float64), (len(obs), 3)))
        if robot is not None:
            params = self.robot_params[robot:robot + 1]
        else:
            params = self.robot_params if len(obs) == self.num_robots else self.robot_params[:1]
        out = pd_actions(np.ascontiguousarray(obs), setpoints, params, np.empty((len(obs), 3)))
        return out[0] if single else out

    def pd_setpoint(self, obs, actions, saturation_margin: float = 0.2) -> np.ndarray:
        """The inverse of `pd_action`: the set-point q^ [rad, rad, m] for which the C11 PD
        law gives the "voltage"-mode actions on the observations (batches as pd_action). The law
        saturates, so a saturated action (|action| >= 0.999) asks ``saturation_margin`` more, to
        stay saturated when the set-point is commanded again.
        """
        single = np.ndim(obs) == 1
        obs = np.atleast_2d(np.asarray(obs, dtype=np.float64))
        actions = np.atleast_2d(np.asarray(actions, dtype=np.float64))
        p = self.robot_params if len(obs) == self.num_robots else self.robot_params[:1]
        critical = obs[:, OBSERVATION_LAYOUT["critical"], None] > 0.5
        limit = np.where(critical, p["wide_voltage_limit"], p["voltage_limit"])
        boost = np.where(np.abs(actions) >= 0.999, 1.0 + saturation_margin, 1.0)
        rates = obs[:, OBSERVATION_LAYOUT["rate"]]
        setpoint = obs[:, OBSERVATION_LAYOUT["q"]] + (actions * boost * limit + p["d_gain"] * rates) / p["p_gain"]
        return setpoint[0] if single else setpoint

    def setpoint_action(self, obs, setpoint, robot: int | None = None) -> np.ndarray:
        """The action that commands the set-point q^ [rad, rad, m] in this task's control mode:
        the clipped "pd" action, or the PD law's voltages (`pd_action`, with ``robot``'s
        parameters where given); batches too.
        """
        if self.control_mode == "pd":
            return np.clip(self._pd_actions(setpoint), -1.0, 1.0)
        return self.pd_action(obs, setpoint, robot)

    @staticmethod
    def check_joints(value, name: str) -> np.ndarray:
        """A start or target q [rad, rad, m] inside the joint range JOINT_LOW..JOINT_HIGH (the
        "pd" mode's set-point range, which the observation bounds are built around).
        """
        return checks.real_array(name, value, (3,), unit="rad, rad, m", low=JOINT_LOW, high=JOINT_HIGH,
                                 range_text=JOINT_RANGE_TEXT)

    # -- episodes ------------------------------------------------------------------------
    def episode_start(self, rng: np.random.Generator, options: dict | None) -> EpisodePlan:
        """The checked start of a new episode from the reset options and the episode RNG: the
        parameters first (drawn where randomized, then ``options["params"]`` overrides), then
        start and target (a randomized target is drawn against the episode's wall).
        """
        options = checks.mapping("reset options", options, RESET_OPTIONS)
        varied = self.randomization.draw(rng) if self.randomization else {}
        if "params" in options:
            varied.update(check_overrides("options['params']", options["params"], self.params))
        params = self.params
        if varied:
            try:
                params = self.params.replace(varied)
            except (KeyError, TypeError, ValueError) as error:
                raise ValueError(f"options['params']: {error}") from None
            problem = within_bounds(params, self.bound_params)
            if problem:
                raise ValueError(f"options['params']: {problem}, built from the construction arguments "
                                 f"params and randomize_params; widen them there")
        if "start" in options:
            start = self.check_joints(options["start"], "options['start']")
        elif self.start_region is not None:
            start = draw_start(rng, self.default_start, self.start_region)
        else:
            start = self.default_start
        if "target" in options:
            target = self.check_joints(options["target"], "options['target']")
        elif self.randomize_target:
            target = draw_target(rng, start, params, self.obstacle)
        else:
            target = self.default_target
        if np.max(np.abs(start - target)) < self.params.task.accuracy:
            raise ValueError(f"start {start.tolist()} is already within acc of the target {target.tolist()}")
        return EpisodePlan(start.copy(), target.copy(), params, varied)

    def reset_robot(self, i: int, rng: np.random.Generator, options: dict | None = None) -> dict:
        """Start a new episode of robot i; returns the reset info (target, start, and params:
        the drawn or overridden parameters, where any).
        """
        plan = self.episode_start(rng, options)
        self.begin_episode(i, plan)
        info = {"target": plan.target, "start": plan.start}
        if plan.varied:
            info["params"] = dict(plan.varied)
        return info

    def params_record(self, params: ScaraParams) -> np.void:
        """The PARAMS record of an episode's parameters (the nominal one is made once)."""
        return self.nominal_record if params is self.params else params.to_record()

    def use_params(self, i: int, params: ScaraParams) -> None:
        """Robot i's parameters for its next episode (its record rewritten only on a change)."""
        if params is not self.episode_params[i]:
            self.robot_params[i] = self.params_record(params)
            self.episode_params[i] = params

    def begin_episode(self, i: int, plan: EpisodePlan) -> None:
        """Robot i at rest at the plan's start, with its target and parameters."""
        start, target = plan.start, plan.target
        self.use_params(i, plan.params)
        if self.actuator is not None:  # before the episode the robot rests: the neutral action
            self.actuator.reset(i, self.setpoint_to_action(start) if self.control_mode == "pd" else np.zeros(3))
        begin_robot(i, start, target, self.robots, self.robot_params, self.step_config, self.constants, self.outcomes, self.obs)

    def snapshot(self, i: int) -> dict:
        """Robot i's state as ``restore`` takes it (copies): state vector, current holds, time,
        the integrator's next step size, steps taken, the target and parameters it holds for, and
        with an action_delay or a rate limit the actuator line's state ("pending", "applied").
        """
        robot = self.robots[i]
        snapshot = {"x": robot["x"].copy(), "hold": robot["hold"].copy(), "t": float(robot["t"]),
                    "step_size": float(robot["step_size"]),
                    "episode_steps": int(self.outcomes[i]["episode_steps"]),
                    "target": self.robot_params[i]["target"].copy(), "params": self.episode_params[i]}
        if self.actuator is not None:
            snapshot["pending"] = self.actuator.pending[i].copy()
            snapshot["applied"] = self.actuator.applied[i].copy()
        return snapshot

    def restore(self, i: int, snapshot: dict) -> None:
        """Robot i, in an episode with the snapshot's target and parameters, put in the
        snapshot's state: the episode goes on from there (its step's reward terms zero). For
        starts along a recorded trajectory, as in reference state initialization. With an
        action_delay or a rate limit the snapshot must hold the actuator line's state of the same
        delay (a snapshot of a task with the same sim-to-real options).
        """
        if self.actuator is not None:
            pending, applied = snapshot.get("pending"), snapshot.get("applied")
            if pending is None or applied is None or np.shape(pending) != self.actuator.pending[i].shape:
                raise ValueError(f"restore: this task's action line (action_delay {self.sim_to_real.action_delay}) "
                                 f"needs a snapshot with its state ('pending', 'applied') of the same delay")
        if snapshot["params"] != self.episode_params[i] or not np.array_equal(snapshot["target"],
                                                                              self.robot_params[i]["target"]):
            raise ValueError(f"restore: robot {i}'s episode has another target or other parameters than the "
                             f"snapshot's (target {np.asarray(snapshot['target']).tolist()}); reset it to those first")
        restore_robot(i, np.asarray(snapshot["x"], dtype=np.float64), np.asarray(snapshot["hold"], dtype=np.int64),
                      float(snapshot["t"]), float(snapshot["step_size"]), int(snapshot["episode_steps"]),
                      self.robots, self.robot_params,
                      self.step_config, self.constants, self.outcomes, self.obs)
        if self.actuator is not None:
            self.actuator.pending[i] = pending
            self.actuator.applied[i] = applied

    # -- steps ---------------------------------------------------------------------------
    def step_robot(self, i: int, action: np.ndarray) -> None:
        """One control step of robot i (action: 3 float64, C-contiguous); raises on bad input
        (nothing changed) or a failed integration.
        """
        clipped = None
        if self.actuator is not None:
            action = check_actions(action, (3,))  # finite before it enters the delay line
            clipped = int(np.count_nonzero(np.abs(action) > 1.0))
            action = self.actuator.apply(np.array([i]), np.clip(action, -1.0, 1.0)[None])[0]
        status = step_robot(i, action, self.robots, self.robot_params, self.step_config, self.constants, self.log,
                            self.outcomes, self.obs)
        if status < 0:
            self._raise_for(status, i, action)
        if clipped is not None:  # the compiled step saw the shaped action: count the given one's
            self.outcomes["clipped"][i] = clipped

    def step_robots(self, active: np.ndarray, actions: np.ndarray, parallel: bool = True) -> None:
        """One control step of every active robot (actions: checked (N, 3) float64), on numba's
        threads, or on the calling thread alone with ``parallel=False``.
        """
        if self.actuator is not None:
            rows = np.flatnonzero(active)
            clipped = np.count_nonzero(np.abs(actions[rows]) > 1.0, axis=1)
            actions = actions.copy()
            actions[rows] = self.actuator.apply(rows, np.clip(actions[rows], -1.0, 1.0))
        if parallel:
            with PARALLEL_LOCK:
                step_robots(active, actions, self.robots, self.robot_params, self.step_config, self.constants, self.log,
                            self.outcomes, self.obs)
        else:  # no thread pool involved: no lock needed
            step_robots_serial(active, actions, self.robots, self.robot_params, self.step_config, self.constants, self.log,
                               self.outcomes, self.obs)
        if self.actuator is not None:
            self.outcomes["clipped"][rows] = clipped
        failed = active & (self.outcomes["status"] < 0)
        if failed.any():
            i = int(np.flatnonzero(failed)[0])
            self._raise_for(int(self.outcomes["status"][i]), i, actions[i])

    def _raise_for(self, status: int, i: int, action) -> None:
        if status == R.STATUS_BAD_ACTION:
            check_actions(action, (3,))  # raises naming it
        where = f"sub-environment {i}: " if self.num_robots > 1 else ""
        raise SimulationError(where + failure_message(status, self.robots[i], self.step_config[0], self.params))

    def observation(self, i: int, rng: np.random.Generator) -> np.ndarray:
        """Robot i's observation as the agent gets it (a copy): with sensor noise, then
        observation noise, drawn from ``rng`` (the episode's generator) where configured.
        """
        options = self.sim_to_real
        if not options.noisy:
            return self.obs[i].copy()
        obs = self.obs[i]
        if options.sensor_noisy:
            obs = sense(obs, options.sensor_std, rng, self.robot_params[i], self.obstacle, self.obs_low,
                        self.obs_high).astype(np.float32)
        if not options.observation_noisy:
            return obs
        return add_noise(obs, options.noise_std, rng, self.obs_low, self.obs_high)

    def observations(self, rngs: list[np.random.Generator]) -> np.ndarray:
        """Every robot's observation as the agents get it (robot i's noise from rngs[i])."""
        if not self.sim_to_real.noisy:
            return self.obs.copy()
        return np.stack([self.observation(i, rng) for i, rng in enumerate(rngs)])

    def terminated(self, outcome) -> bool | np.ndarray:
        """Success, or a collision where collisions terminate (one outcome or an array of them)."""
        return outcome["reached"] | ((outcome["collisions"] > 0) & (self.collision_mode == "terminate"))

    def info(self, index: int | None = None) -> dict:
        """The step info of robot ``index`` (Python scalars, the single environment's form, with
        reach_time only on success) or of all robots (arrays, the vector environment's form, with
        reach_time masked by _reach_time).
        """
        if index is not None:
            return self._robot_info(index)
        outcomes, robots = self.outcomes, self.robots
        collided = outcomes["collisions"] > 0
        reached = outcomes["reached"]
        info = {
            "reward_terms": {term: outcomes[term] for term in REWARD_TERMS},
            "is_success": reached,
            "cost": collided.astype(np.float64),
            "collision": collided,
            "collisions": outcomes["episode_collisions"],
            "critical": robots["critical"] == 1,
            "time": robots["t"],
            "energy": robots["x"][..., R.ENERGY],
            "clipped_actions": outcomes["clipped"],
        }
        info["reach_time"] = np.where(reached, outcomes["reach_time"], np.nan)
        info["_reach_time"] = reached
        if self.actuator is not None:
            info["applied_action"] = self.actuator.applied
        info["reward_terms"] = {term: value.copy() for term, value in info["reward_terms"].items()}
        return {key: (value.copy() if isinstance(value, np.ndarray) else value) for key, value in info.items()}

    def _robot_info(self, i: int) -> dict:
        """info(i): the same entries as Python scalars, plus current_limited, voltage, target."""
        packed = pack_info(i, self.robots, self.robot_params, self.outcomes, self._info_buffer)
        scalars = INFO_SCALARS
        values = packed[:scalars].tolist()
        terms = dict(zip(REWARD_TERMS, values[:len(REWARD_TERMS)]))
        reached, collisions, episode_collisions, critical, t, energy, clipped, reach_time = values[len(REWARD_TERMS):]
        collisions = int(collisions)
        reached = reached != 0.0
        info = {
            "reward_terms": terms,
            "is_success": reached,
            "cost": 1.0 if collisions > 0 else 0.0,
            "collision": collisions > 0,
            "collisions": int(episode_collisions),
            "critical": critical == 1.0,
            "time": t,
            "energy": energy,
            "clipped_actions": int(clipped),
            "current_limited": packed[scalars:scalars + 3] != 0.0,
            "voltage": packed[scalars + 3:scalars + 6].copy(),
            "target": packed[scalars + 6:scalars + 9].copy(),
        }
        if reached:
            info["reach_time"] = reach_time
        if self.actuator is not None:
            info["applied_action"] = self.actuator.applied[i].copy()
        return info
