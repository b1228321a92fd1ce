"""The environments' declared state surface: what agents and wrappers may read and call.

The task object (`ScaraTask`, an env's ``_task``) is the envs'
engine and internal. What agents, policies, hooks and wrappers need of it is declared here, as
documented methods and properties of the envs:

- `TaskSurface` (every env: single, CPU vector, CUDA vector): the configuration
  (``config``, ``params``, ``control_mode`` ...) and the pure "pd" set-point maps
  (``setpoint_to_action``, ``action_to_setpoint``).
- `RobotsSurface` (the CPU vector env): per robot ``snapshot``/``restore``, the
  noise-free observation, ``reset_robot``, the episode parameters, the targets and the
  set-point maps that need a robot's parameters (``setpoint_action``, ``pd_action``,
  ``pd_setpoint``). The single env (`ScaraEnv`) has the same
  methods without the robot index.
"""

from __future__ import annotations

import numpy as np

from scara_gym.envs.config import EnvConfig
from scara_gym.envs.task import RewardWeights
from scara_gym.model import checks
from scara_gym.model.params import ScaraParams


class TaskSurface:
    """The configuration and the pure set-point maps of an env built on a task (``self._task``)."""

    _task = None  # set by the env's constructor

    @property
    def config(self) -> EnvConfig:
        """The `EnvConfig` this env was built from (its defaults, the
        given config and the keyword overrides merged); ``ScaraTask(env.config)`` models it.
        """
        return self._task.env_config

    @property
    def params(self) -> ScaraParams:
        """The nominal model parameters (each episode's may differ: ``episode_params``)."""
        return self._task.params

    @property
    def control_mode(self) -> str:
        """"pd" (actions are set-points) or "voltage" (actions are armature voltages)."""
        return self._task.control_mode

    @property
    def obstacle(self) -> bool:
        """Whether the wall of task c is in the way."""
        return self._task.obstacle

    @property
    def collision_mode(self) -> str:
        """"terminate" (a collision ends the episode) or "penalty" (the arm passes through)."""
        return self._task.collision_mode

    @property
    def randomize_target(self) -> bool:
        """Whether each episode draws its target."""
        return self._task.randomize_target

    @property
    def reward_weights(self) -> RewardWeights:
        """The weights of the reward's terms."""
        return self._task.reward_weights

    @property
    def control_dt(self) -> float:
        """The control step [s]."""
        return self._task.control_dt

    @property
    def time_limit(self) -> float:
        """The time the episode's ``time_left`` observation counts down from [s]."""
        return self._task.time_limit

    def setpoint_to_action(self, setpoint) -> np.ndarray:
        """The "pd" action that commands a set-point.

        Args:
            setpoint: q^ [rad, rad, m], 3 numbers.

        Returns:
            The "pd"-mode action (float64, shape (3,), not clipped to [-1, 1]).
        """
        return self._task.setpoint_to_action(setpoint)

    def action_to_setpoint(self, action) -> np.ndarray:
        """The set-point a "pd" action commands (the inverse of `setpoint_to_action`).

        Args:
            action: one "pd" action (3,) or a batch (n, 3).

        Returns:
            q^ [rad, rad, m], float64, the shape of ``action``.
        """
        return self._task.action_to_setpoint(action)


class RobotsSurface(TaskSurface):
    """The per-robot state surface of the CPU vector env (robots indexed 0 .. num_envs - 1)."""

    def _robot(self, robot) -> int:
        return checks.integer("robot", robot, 0, self._task.num_robots - 1)

    @property
    def targets(self) -> np.ndarray:
        """Every robot's target q^ [rad, rad, m] of its current episode, shape (num_envs, 3) (a copy)."""
        return self._task.robot_params["target"].copy()

    @property
    def episode_params(self) -> list[ScaraParams]:
        """Every robot's model parameters in its current episode (``params`` unless randomized or
        overridden), a list over the robots.
        """
        return list(self._task.episode_params)

    def snapshot(self, robot: int) -> dict:
        """Robot ``robot``'s state, to put it back with `restore`.

        Args:
            robot: the robot's index.

        Returns:
            A dict of copies: "x" (state vector), "hold" (current holds), "t" (time [s]),
            "step_size" (the integrator's next step), "episode_steps", "target" and "params"
            (the episode's), and with an action_delay or a rate limit the actuator line's
            "pending" and "applied" actions. Restoring it makes the robot go on bit for bit
            as it went on from the snapshot.
        """
        return self._task.snapshot(self._robot(robot))

    def restore(self, robot: int, snapshot: dict) -> None:
        """Put robot ``robot`` in a snapshot's state; its episode goes on from there (the step's
        reward terms zero, its episode not ended). For starts along a recorded trajectory, as in
        reference state initialization.

        Args:
            robot: the robot's index; its current episode must have the snapshot's target and
                parameters (reset it to those first).
            snapshot: a `snapshot` of an env with the same sim-to-real options.

        Raises:
            ValueError: the target, parameters or actuator line differ from the snapshot's.
        """
        robot = self._robot(robot)
        self._task.restore(robot, snapshot)
        self._robot_restarted(robot)

    def reset_robot(self, robot: int, options: dict | None = None, rng: np.random.Generator | None = None) -> dict:
        """Start a new episode of one robot now, between steps (the others go on).

        Args:
            robot: the robot's index.
            options: the reset options ("target", "start", "params"), as ``reset`` takes them.
            rng: the generator its episode draws from (start, target, parameters where drawn);
                None: the robot's own.

        Returns:
            The robot's reset info: "target", "start", and "params" where drawn or set. Its
            observation is `noise_free_observation` (no noise is drawn here).
        """
        robot = self._robot(robot)
        info = self._task.reset_robot(robot, self._rngs[robot] if rng is None else rng, options)
        self._robot_restarted(robot)
        return info

    def _robot_restarted(self, robot: int) -> None:
        """The env's bookkeeping of a robot put in a running episode by restore or reset_robot."""

    def noise_free_observation(self, robot: int) -> np.ndarray:
        """Robot ``robot``'s observation of its true state, without sensor or observation noise.

        Args:
            robot: the robot's index.

        Returns:
            The flat observation (float32, shape (18,), a copy); what ``step`` returned for the
            robot where the env adds no noise.
        """
        return self._task.obs[self._robot(robot)].copy()

    def setpoint_action(self, obs, setpoint, robot: int | None = None) -> np.ndarray:
        """The action that commands a set-point in this env's control mode: the clipped "pd"
        action, or in "voltage" mode the C11 PD law's voltages on the observation (`pd_action`).

        Args:
            obs: one observation (18,) or a batch (n, 18).
            setpoint: q^ [rad, rad, m], (3,) or (n, 3).
            robot: whose parameters the PD law uses; None: robot i's for row i of a batch over all
                robots, else robot 0's.

        Returns:
            The action(s), float64, (3,) or (n, 3).
        """
        return self._task.setpoint_action(obs, setpoint, None if robot is None else self._robot(robot))

    def pd_action(self, obs, setpoint, robot: int | None = None) -> np.ndarray:
        """The "voltage"-mode action that applies the C11 PD law to a set-point on an observation:
        U / limit, with the widened limit where the observation says critical (what "pd" mode does).

        Args:
            obs: one observation (18,) or a batch (n, 18).
            setpoint: q^ [rad, rad, m], (3,) or (n, 3).
            robot: whose parameters; None: robot i's for row i of a batch over all robots, else robot 0's.

        Returns:
            The voltage action(s), float64, (3,) or (n, 3).
        """
        return self._task.pd_action(obs, setpoint, None if robot is None else self._robot(robot))

    def pd_setpoint(self, obs, actions, saturation_margin: float = 0.2) -> np.ndarray:
        """The inverse of `pd_action`: the set-point for which the C11 PD law gives the
        "voltage"-mode actions on the observations.

        Args:
            obs: one observation (18,) or a batch (n, 18); a batch over all robots uses robot i's
                parameters for row i, else robot 0's.
            actions: the voltage action(s), (3,) or (n, 3).
            saturation_margin: a saturated action (|action| >= 0.999) asks this share more, to
                stay saturated when the set-point is commanded again.

        Returns:
            q^ [rad, rad, m], float64, (3,) or (n, 3).
        """
        return self._task.pd_setpoint(obs, actions, saturation_margin)
