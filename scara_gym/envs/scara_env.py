"""ScaraEnv, the env of every registered id: the C11 point-to-point move with the wall of task c in the way."""

from __future__ import annotations

import inspect
import textwrap

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from scara_gym.envs.config import EnvConfig, arguments_markdown, make_config
from scara_gym.envs.surface import TaskSurface
from scara_gym.envs.task import OBSERVATION_NAMES, ScaraTask, check_actions, observation_table
from scara_gym.model import checks, records as R
from scara_gym.model.params import ScaraParams


class ScaraEnv(TaskSurface, gym.Env):
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

{OBSERVATIONS}

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

    ``ScaraEnv(config=None, render_mode=None, **overrides)``: ``config`` is an
    `EnvConfig` (default ``EnvConfig()``, the latest id's
    arguments), and every field of it can be given as a keyword, over ``config``:

{ARGUMENTS}

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
    config_defaults = EnvConfig()
    """the configuration an instance starts from before its config and overrides (a subclass's own)"""

    def __init__(self, config: EnvConfig | None = None, *, render_mode: str | None = None, **overrides) -> None:
        self._task = ScaraTask(make_config(config, overrides, self.config_defaults), num_robots=1)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, "
                             f"got {render_mode!r}")
        task = self._task
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

    # -- the state surface (scara_gym.envs.surface): what agents and wrappers use ------------
    @property
    def episode_params(self) -> ScaraParams:
        """The model parameters of the current episode: ``params`` unless randomized or overridden."""
        return self._task.episode_params[0]

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
        """The current episode's target q^ [rad, rad, m] (float64, a copy)."""
        return self._task.robot_params["target"][0].copy()

    def snapshot(self) -> dict:
        """The robot's state, to put it back with `restore`.

        Returns:
            A dict of copies: "x" (state vector), "hold" (current holds), "t" (time [s]),
            "step_size" (the integrator's next step), "episode_steps", "target" and "params"
            (the episode's), and with an action_delay or a rate limit the actuator line's
            "pending" and "applied" actions. Restoring it makes the episode go on bit for bit
            as it went on from the snapshot (the observation noise aside, drawn from the env's
            generator).
        """
        return self._task.snapshot(0)

    def restore(self, snapshot: dict) -> None:
        """Put the robot in a snapshot's state; the episode goes on from there (the step's reward
        terms zero, the episode not ended). For starts along a recorded trajectory, as in
        reference state initialization, and for look-ahead (a shield's, a planner's).

        Args:
            snapshot: a `snapshot` (of this env or a vector env's robot) of an env with the
                same sim-to-real options; the current episode must have its target and
                parameters (reset to those first).

        Raises:
            ValueError: the target, parameters or actuator line differ from the snapshot's.
        """
        self._task.restore(0, snapshot)
        self._needs_reset = False
        self._trace = [self._tip()]

    def noise_free_observation(self) -> np.ndarray:
        """The observation of the robot's true state, without sensor or observation noise.

        Returns:
            The flat observation (float32, shape (18,), a copy); what ``step`` returned where the
            env adds no noise (a goal env's flat observation too).
        """
        return self._task.obs[0].copy()

    def setpoint_action(self, obs, setpoint) -> np.ndarray:
        """The action that commands a set-point in this env's control mode: the clipped "pd"
        action, or in "voltage" mode the C11 PD law's voltages on the observation (`pd_action`).

        Args:
            obs: one flat observation (18,) or a batch (n, 18).
            setpoint: q^ [rad, rad, m], (3,) or (n, 3).

        Returns:
            The action(s), float64, (3,) or (n, 3).
        """
        return self._task.setpoint_action(obs, setpoint)

    def pd_action(self, obs: np.ndarray, setpoint: np.ndarray) -> np.ndarray:
        """The "voltage"-mode action that applies the C11 PD law to a set-point on an observation:
        U / limit, with the widened limit where the observation says critical (what "pd" mode
        does, evaluated once per control step), with the episode's parameters.

        Args:
            obs: one flat observation (18,) or a batch (n, 18).
            setpoint: q^ [rad, rad, m], (3,) or (n, 3).

        Returns:
            The voltage action(s), float64, (3,) or (n, 3).
        """
        return self._task.pd_action(obs, setpoint)

    def pd_setpoint(self, obs, action, saturation_margin: float = 0.2) -> np.ndarray:
        """The inverse of `pd_action`: the set-point for which the C11 PD law gives the
        "voltage"-mode action on the observation.

        Args:
            obs: one flat observation (18,) or a batch (n, 18).
            action: the voltage action(s), (3,) or (n, 3).
            saturation_margin: a saturated action (|action| >= 0.999) asks this share more, to
                stay saturated when the set-point is commanded again.

        Returns:
            q^ [rad, rad, m], float64, (3,) or (n, 3).
        """
        return self._task.pd_setpoint(obs, action, saturation_margin)

    # -- API ---------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode (Gymnasium's Env.reset): the observation and the info of its first state."""
        super().reset(seed=checks.seed("seed", seed))
        info = self._task.reset_robot(0, self.np_random, options)
        self._needs_reset = False
        self._trace = [self._tip()]
        if self.render_mode == "human":
            self.render()
        return self._task.observation(0, self.np_random), info

    def step(self, action):
        """One control step of the robot (Gymnasium's Env.step): observation, reward, terminated, truncated, info."""
        if self._needs_reset:
            raise RuntimeError("the episode has ended (or never started): call reset() before step()")
        if not (type(action) is np.ndarray and action.shape == (3,) and action.dtype.char in "fd"
                and action.flags.c_contiguous):
            action = check_actions(action, (3,))  # converts, or raises naming the problem
        task = self._task
        task.step_robot(0, action)
        info = task.info(0)
        terminated = info["is_success"] or (info["collision"] and task.collision_mode == "terminate")
        self._needs_reset = terminated
        if self.render_mode is not None:
            self._trace.append(self._tip())
        if self.render_mode == "human":
            self.render()
        return self._task.observation(0, self.np_random), float(self._reward[0]), terminated, False, info

    # -- helpers -----------------------------------------------------------------------
    def _tip(self) -> tuple[float, float]:
        tip = self._outcome["tip"]
        return float(tip[0]), float(tip[1])

    # -- rendering ---------------------------------------------------------------------
    def render(self):
        """The frame of the render mode: an RGB array, or the window drawn ("human")."""
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
        """Close the render window, if one is open."""
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
        self._robot = self._task.robots[0]
        self._outcome = self._task.outcomes[0]
        self._reward = self._task.outcomes["reward"]


RENDER_MODE_DOC = ('"rgb_array" (headless) or "human" (a window; without a display the frames are drawn '
                   'off-screen, with one warning at construction); fixed at construction.')
"""the card's line for render_mode, which is the env's own argument (not the task's)"""


def card(summary: str, config: EnvConfig, history: str) -> str:
    """ScaraEnv's card for ``config``: ``summary`` (title and paragraphs), the spaces, reward,
    starting state and episode end, the observation bounds and argument defaults of
    ``config``, and ``history`` (the version history's lines); each registered variant's
    card is one of these (scara_gym.envs.variants).
    """
    body = _BODY.replace("{OBSERVATIONS}", textwrap.indent(observation_table(ScaraTask(config)), "    "))
    body = body.replace("{ARGUMENTS}", arguments_markdown(config, (("render_mode", None, RENDER_MODE_DOC),),
                                                          indent="    "))
    return f"{textwrap.indent(inspect.cleandoc(summary), '    ')}\n\n{body}    ## Version history\n\n" \
           f"{textwrap.indent(inspect.cleandoc(history), '    ')}\n    "


_SUMMARY, _, _REST = ScaraEnv.__doc__.partition("\n\n    ## Action space")
_BODY, _, _HISTORY = ("    ## Action space" + _REST).partition("    ## Version history\n\n")
ScaraEnv.__doc__ = card(_SUMMARY, ScaraEnv.config_defaults, _HISTORY)
