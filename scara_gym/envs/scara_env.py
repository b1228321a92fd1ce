"""ScaraEnv, the env of every registered id: the C11 point-to-point move with the wall of task c in the way."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from scara_gym.envs.task import OBSERVATION_NAMES, RewardWeights, ScaraTask, check_actions
from scara_gym.model import checks, records as R
from scara_gym.model.params import ScaraParams


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
    the tip becomes critical. With ``action_delay`` or ``action_rate_limit`` (off by
    default) the applied action lags the given one, see the arguments.

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
    height margin follow the parameters (the table shows the defaults). With
    ``observation_noise`` (off by default) Gaussian noise is added to the returned
    observation, which is then clipped to these bounds.

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

    With ``randomize_params``, model parameters are drawn per episode, before the target,
    from uniform ranges (``scara_gym.envs.randomization``): the preset "physics" (or True)
    draws the load mass (nominal x [0.5, 2.5]), the link masses (x [0.9, 1.1]) and per axis
    the motor resistance (x [0.9, 1.3]), torque constant (x [0.9, 1.1]) and current limit
    (x [0.8, 1.1]); "wall" draws x_obs (nominal +- 0.04 m) and h_obs (+- 0.03 m); "all"
    both; a dict {dotted path: (low, high)} gives ranges of its own, in the parameter's
    unit. ``reset(options={"params": {"arm.load_mass": 1.0}})`` sets parameters for one
    episode, over any draw. The drawn and set values are in the reset info
    (``info["params"]``) and in ``env.unwrapped.episode_params``.

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
    reach_time (s, the located instant) on the step that reaches the target;
    applied_action (the action the robot applied, in [-1, 1]) with ``action_delay`` or
    ``action_rate_limit``. The reset
    info holds target and start, and params (dotted path -> value) where parameters were
    drawn or set for the episode.

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
    - rtol (1e-07): relative integration tolerance inside the step (scipy's meaning),
      in [1e-14, 1e-2]; the default is the latest id's (Scara-C11-v2); Scara-C11-v0
      registers 1e-5, Scara-C11-v1 1e-6.
    - atol (1e-09): absolute integration tolerance inside the step, in [1e-16, 1e-2];
      Scara-C11-v0 registers 1e-6, Scara-C11-v1 1e-8. How close a tolerance stays to a
      tight-tolerance run is measured by ``scara-c11 accuracy``.
    - exact_switches (True): locate every mode switch inside the integration steps
      (a current limit or the PD law's saturation reached and left within one step is
      found; the saturation is a located switch, not a kink). False is the first
      releases' integration (Scara-C11-v0), which sees switches at the ends of
      integration steps only.
    - tolerance_weights (None): a dict from state groups ("q", "rate", "current",
      "energy") to a factor in [1e-3, 1e3] on rtol and atol for that group's
      components (the others 1), e.g. {"q": 0.03, "current": 30}; no id registers it
      (at v2's tolerances those weights miss the current target on a held-out episode).
    - randomize_params (False): False, True ("physics"), "physics", "wall", "all" or a
      dict {dotted path: (low, high)}: parameters drawn per episode, see the starting
      state; the observation bounds then hold the ranges' ends.
    - observation_noise (None): sim-to-real: {field: standard deviation} in the field's
      unit, e.g. {"q": 1e-3, "rate": 0.05, "current": 0.02}; fields of the observation
      ("q", "rate", "current", "target_error", "tip_x", ...: a vector field's std applies
      to each entry) or entries by the table's names ("q3"). Zero-mean Gaussian noise per
      step from the episode's generator, added to the returned observation only (the
      physics, reward and episode end see the true state). Each entry gets its own noise:
      noise on q does not reach target_error or the tip; for that, use sensor_noise.
    - action_delay (0): sim-to-real: dead time in control steps, in [0, 100]: the action
      given at step t is applied at step t + k; the first k steps apply the neutral
      action (the start as set-point in "pd" mode, 0 V in "voltage" mode).
    - action_rate_limit (None): sim-to-real: the applied action moves towards the
      (delayed) given one by at most this many action units per second (the action spans
      [-1, 1]; e.g. 20 allows 0.2 per 0.01 s step), starting from the neutral action.
    - render_mode (None): "rgb_array" (headless) or "human" (a window; without a display the
      frames are drawn off-screen, with one warning at construction).
    - sensor_noise (None): sim-to-real: noisy sensors, {channel: standard deviation} over
      "q", "rate" and "current" (or entries "q1" ... "current3"), e.g. {"q": 1e-3, "rate":
      0.01, "current": 0.02}: the noise is added to the measured q, rates and currents and
      target_error, tip_x, tip_y, wall_distance and height_margin are computed from the noisy
      measurements (as a controller computes them from its sensors); drawn before any
      observation_noise, from the episode's generator. Not on the CUDA vector env.
    - randomize_start (False): True draws the start per episode as ``start`` + uniform
      offsets in q1, q2 in [-0.05, 0.05] rad, q3 in [0, 0.05] m (the evaluation protocol's
      start region), after the parameters and before the target; (low, high) gives offsets
      of its own [rad, rad, m]. ``reset(options={"start": ...})`` overrides it.

    ## Version history

    The ids differ only in the integration arguments they register (``scara_gym.ENV_VERSIONS``);
    the class defaults are the latest id's (v2's): ``ScaraEnv()`` is ``gym.make("Scara-C11-v2")``
    without the time limit. v0 and v1 stay registered and frozen for results made on them.

    - v2: v1's exact switches (``exact_switches=True``) at ``rtol=1e-7``, ``atol=1e-9``:
      within every accuracy target of ``scara-c11 accuracy``, including the currents just
      after the voltage jump at the critical switch in "voltage" mode, at about 1.45x v1's
      right-hand-side evaluations per step. The same physics as v1: policies carry over.
    - v1: exact switches (``exact_switches=True``) and ``rtol=1e-6``, ``atol=1e-8``: every
      current-limit, PD-saturation, critical, wall and target switch is located inside
      the integration steps; at these tolerances the states follow an rtol 1e-10 run within
      the accuracy targets of ``scara-c11 accuracy`` (see the README for the figures and
      the one exception, the voltage jump at the critical switch in "voltage" mode).
    - v0: first release (``rtol=1e-5``, ``atol=1e-6``, ``exact_switches=False``).

    Later added to every id, without a change to what existing arguments do: ``sensor_noise``
    (noisy sensors with the derived entries computed from them; ``observation_noise`` keeps its
    per-entry meaning) and ``randomize_start`` (starts drawn per episode). In scara_gym 0.4.0 the
    class defaults moved from v0's integration to v2's; no registered id changed.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 100}
    observation_names = OBSERVATION_NAMES

    def __init__(self, control_mode: str = "pd", obstacle: bool = True, collision: str = "terminate",
                 target=None, start=None, randomize_target: bool = False,
                 reward_weights: RewardWeights | dict | None = None, control_dt: float = 0.01,
                 time_limit: float = 3.0, params: ScaraParams | dict | None = None,
                 rtol: float = 1e-7, atol: float = 1e-9, exact_switches: bool = True,
                 randomize_params=False, observation_noise: dict | None = None, action_delay: int = 0,
                 action_rate_limit: float | None = None, render_mode: str | None = None,
                 sensor_noise: dict | None = None, randomize_start=False,
                 tolerance_weights: dict | None = None) -> None:
        self.task = ScaraTask(control_mode, obstacle, collision, target, start, randomize_target,
                              reward_weights, control_dt, time_limit, params, rtol, atol,
                              exact_switches, num_robots=1, randomize_params=randomize_params,
                              observation_noise=observation_noise, action_delay=action_delay,
                              action_rate_limit=action_rate_limit, sensor_noise=sensor_noise,
                              randomize_start=randomize_start, tolerance_weights=tolerance_weights)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, "
                             f"got {render_mode!r}")
        task = self.task
        self.render_mode = render_mode
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / task.control_dt}
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.observation_space = spaces.Box(task.obs_low, task.obs_high, dtype=np.float32)
        self._robot = task.robots[0]
        self._outcome = task.outcomes[0]
        self._reward = task.outcomes["reward"]
        self._needs_reset = True
        self._renderer = None
        self._trace = []
        self._window = False
        if render_mode == "human":
            from scara_gym.envs.rendering import has_display
            self._window = has_display()
            if not self._window:  # a headless machine (CI, a cluster node, Gymnasium's check_env there)
                gym.logger.warn("render_mode='human' without a display (DISPLAY or WAYLAND_DISPLAY is not set): "
                                "frames are drawn off-screen and shown nowhere; use render_mode='rgb_array' to get them")

    # -- the task's configuration, read-only ---------------------------------------------
    params = property(lambda self: self.task.params)
    control_mode = property(lambda self: self.task.control_mode)
    obstacle = property(lambda self: self.task.obstacle)
    collision_mode = property(lambda self: self.task.collision_mode)
    randomize_target = property(lambda self: self.task.randomize_target)
    reward_weights = property(lambda self: self.task.reward_weights)
    control_dt = property(lambda self: self.task.control_dt)
    time_limit = property(lambda self: self.task.time_limit)

    @property
    def episode_params(self) -> ScaraParams:
        """The parameters of the current episode: ``params`` unless randomized or overridden."""
        return self.task.episode_params[0]

    @property
    def state(self) -> np.ndarray:
        """The robot's state vector (a copy): q1, q2, q3, rates, currents, energy."""
        return self._robot["x"].copy()

    @property
    def time(self) -> float:
        """Simulated time of the episode [s]."""
        return float(self._robot["t"])

    @property
    def target(self) -> np.ndarray:
        return self.task.robot_params["target"][0].copy()

    def setpoint_to_action(self, setpoint) -> np.ndarray:
        """The "pd" action (float64, unclipped) that commands the set-point q^ [rad, rad, m]."""
        return self.task.setpoint_to_action(setpoint)

    def action_to_setpoint(self, action) -> np.ndarray:
        return self.task.action_to_setpoint(action)

    def pd_action(self, obs, setpoint) -> np.ndarray:
        """The "voltage"-mode action that applies the C11 PD law to a set-point on an
        observation (see :meth:`ScaraTask.pd_action`)."""
        return self.task.pd_action(obs, setpoint)

    # -- API ---------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=checks.seed("seed", seed))
        info = self.task.reset_robot(0, self.np_random, options)
        self._needs_reset = False
        self._trace = [self._tip()]
        if self.render_mode == "human":
            self.render()
        return self.task.observation(0, self.np_random), info

    def step(self, action):
        if self._needs_reset:
            raise RuntimeError("the episode has ended (or never started): call reset() before step()")
        if not (type(action) is np.ndarray and action.shape == (3,) and action.dtype.char in "fd"
                and action.flags.c_contiguous):
            action = check_actions(action, (3,))  # converts, or raises naming the problem
        task = self.task
        task.step_robot(0, action)
        info = task.info(0)
        terminated = info["is_success"] or (info["collision"] and task.collision_mode == "terminate")
        self._needs_reset = terminated
        if self.render_mode is not None:
            self._trace.append(self._tip())
        if self.render_mode == "human":
            self.render()
        return self.task.observation(0, self.np_random), float(self._reward[0]), terminated, False, info

    # -- helpers -----------------------------------------------------------------------
    def _tip(self) -> tuple[float, float]:
        tip = self._outcome["tip"]
        return float(tip[0]), float(tip[1])

    # -- rendering ---------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' "
                            "or 'human' to gym.make")
            return None
        if self._renderer is None:
            from scara_gym.envs.rendering import ScaraRenderer
            self._renderer = ScaraRenderer(self.params, human=self._window)
        self._renderer.set_params(self.episode_params)  # a randomized wall is drawn where it is
        frame = self._renderer.draw(
            q=self._robot["x"][R.Q:R.Q + 3], target=self.target, trace=self._trace, obstacle=self.obstacle,
            critical=bool(self._robot["critical"]), time=self.time,
            collisions=int(self._outcome["episode_collisions"]))
        return frame if self.render_mode == "rgb_array" else None

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_renderer"] = None
        for view in ("_robot", "_outcome", "_reward"):  # views into the task's arrays: re-made on load
            del state[view]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._robot = self.task.robots[0]
        self._outcome = self.task.outcomes[0]
        self._reward = self.task.outcomes["reward"]
