"""Native vector environment: N robots stepped in one parallel compiled call.

``gym.make_vec(ID, num_envs=N, vectorization_mode="vector_entry_point")`` for any registered id.
Sub-environment i behaves exactly as ``gym.make(ID, ...)`` reset with
seed ``seed + i`` (the same compiled control step, bit for bit).

Autoreset: ``autoreset_mode="NextStep"`` (Gymnasium's default): the step after an
episode ends resets that robot and returns its first observation with reward 0,
terminated and truncated False. ``"SameStep"``: the ending step already returns the
reset observation; the final observation and info are in ``info["final_obs"]`` and
``info["final_info"]`` (masked by ``info["_final_obs"]``), as the stable-baselines3
adapter needs. ``"Disabled"``: no robot is reset by ``step``; ``reset(options={"reset_mask":
mask})`` resets the robots where ``mask`` is True (each as the single env reset with its seed,
bit for bit) and leaves the others as they are, and stepping a robot whose episode has ended
without resetting it is an error that names it (as the single env's ``step`` after the end).
"""

from __future__ import annotations

import copy

import numba
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from scara_gym.envs.config import EnvConfig, make_config
from scara_gym.envs.surface import RobotsSurface
from scara_gym.envs.task import RESET_OPTIONS, ScaraTask, check_actions, vector_seeds
from scara_gym.model import checks


def check_autoreset_mode(autoreset_mode) -> AutoresetMode:
    """"NextStep", "SameStep" or "Disabled" (Gymnasium's names or enum members)."""
    try:
        return AutoresetMode(autoreset_mode)
    except ValueError:
        raise ValueError(f"autoreset_mode must be 'NextStep', 'SameStep' or 'Disabled', got {autoreset_mode!r}") \
            from None


def check_reset_mask(options: dict, num_envs: int, autoreset_mode: AutoresetMode) -> np.ndarray | None:
    """The reset options' "reset_mask" (taken out of ``options``): None, or a bool array of
    shape (num_envs,) with a True, in "Disabled" autoreset mode only (Gymnasium's rules).
    """
    if "reset_mask" not in options:
        return None
    mask = options.pop("reset_mask")
    if autoreset_mode != AutoresetMode.DISABLED:
        raise ValueError(f"options['reset_mask'] needs autoreset_mode='Disabled' (this env's is "
                         f"{autoreset_mode.value!r}: it resets ended robots itself)")
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (num_envs,) or not mask.any():
        raise ValueError(f"options['reset_mask'] must be a numpy bool array of shape ({num_envs},) with at least "
                         f"one True, got {mask!r}")
    return mask.copy()


class ScaraVectorEnv(RobotsSurface, VectorEnv):
    """N copies of the env of a registered id (the same arguments as ScaraEnv: ``config`` and
    keyword overrides of its fields), stepped in parallel.

    Extra arguments: num_envs, max_episode_steps (300: the registered time limit),
    autoreset_mode ("NextStep", "SameStep" or "Disabled"), num_threads (numba threads of the parallel
    step; None: all, numba's NUMBA_NUM_THREADS, which defaults to the number of cores; give 1
    where another library, e.g. torch in training, takes the cores between steps). Rendering is not supported in the
    vector environment (render_mode must be None). info holds arrays over the robots:
    is_success, cost, collision, collisions, critical, time, energy, clipped_actions,
    reward_terms (a dict of arrays) and reach_time (masked by ``_reach_time``). With
    ``randomize_params`` every robot draws its own parameters per episode, as the single
    environment seeded ``seed + i`` does; the reset info's ``params`` holds one array per
    drawn path over the robots. The sim-to-real options (observation_noise, action_delay,
    action_rate_limit) act per robot as in the single environment: robot i's noise comes from
    its own generator, and ``info["applied_action"]`` holds every robot's applied action.

    The state surface per robot (``snapshot``/``restore``, ``reset_robot``,
    ``noise_free_observation``, ``targets``, ``episode_params``, the set-point maps) and the
    configuration (``config``, ``params``, ``control_mode`` ...) are documented in
    `scara_gym.envs.surface`.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
    config_defaults = EnvConfig()
    """the configuration ``config`` and the keyword overrides start from (a subclass's own)"""

    def __init__(self, num_envs: int = 1, max_episode_steps: int = 300,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 num_threads: int | None = None, config: EnvConfig | None = None, **kwargs) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if isinstance(max_episode_steps, bool) or not isinstance(max_episode_steps, (int, np.integer)) \
                or max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be an integer >= 1, got {max_episode_steps!r}")
        autoreset_mode = check_autoreset_mode(autoreset_mode)
        available = numba.config.NUMBA_NUM_THREADS
        if num_threads is None:
            num_threads = available
        if isinstance(num_threads, bool) or not isinstance(num_threads, (int, np.integer)) \
                or not 1 <= num_threads <= available:
            raise ValueError(f"num_threads must be an integer in [1, {available}] (numba's threads), "
                             f"got {num_threads!r}")
        self.num_threads = int(num_threads)
        if kwargs.pop("render_mode", None) is not None:
            raise ValueError("the vector environment does not render; use render_mode=None "
                             "(render a single env instead)")
        self._task = task = ScaraTask(make_config(config, kwargs, self.config_defaults), num_robots=int(num_envs))
        self.num_envs = int(num_envs)
        self.max_episode_steps = int(max_episode_steps)
        self.metadata = {**type(self).metadata, "autoreset_mode": autoreset_mode}
        self.autoreset_mode = autoreset_mode
        self.render_mode = None
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.single_observation_space = spaces.Box(task.obs_low, task.obs_high, dtype=np.float32)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._rngs: list[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(self.num_envs)]
        self._prev_done = np.zeros(self.num_envs, dtype=bool)
        self._started = False

    def _robot_restarted(self, robot: int) -> None:
        self._prev_done[robot] = False  # in a running episode: no autoreset, no "ended" error
        if self._started:
            self._obs[robot] = self._task.obs[robot]  # what a masked reset keeps for it

    # -- episodes ----------------------------------------------------------------------
    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Start every robot's episode (Gymnasium's VectorEnv.reset); seed: one, or one per robot."""
        seeds = vector_seeds(seed, self.num_envs)
        options = checks.mapping("reset options", options, (*RESET_OPTIONS, "reset_mask"))
        mask = check_reset_mask(options, self.num_envs, self.autoreset_mode)
        if mask is not None and not self._started:
            raise RuntimeError("options['reset_mask']: call reset() without a mask first (no robot has begun)")
        robots = range(self.num_envs) if mask is None else np.flatnonzero(mask)
        # every reset robot's start, target and parameters are checked before any robot changes
        rngs = {i: self._rngs[i] if seeds[i] is None else seeding.np_random(seeds[i])[0] for i in robots}
        plans = {i: self._task.episode_start(rng, options) for i, rng in rngs.items()}
        for i, plan in plans.items():
            self._rngs[i] = rngs[i]
            self._task.begin_episode(i, plan)
        self._prev_done[list(robots)] = False
        self._started = True
        info = {"target": self.targets}
        varied = sorted({path for plan in plans.values() for path in plan.varied})
        if varied:  # the drawn or overridden parameters, one array per path over the robots
            info["params"] = {path: np.array([plans[i].varied.get(path, np.nan) if i in plans else np.nan
                                              for i in range(self.num_envs)]) for path in varied}
        if mask is None:
            self._obs = self._task.observations(self._rngs)
        else:  # the others keep their last observation: no noise is drawn for them
            info["_target"] = mask
            for i in robots:
                self._obs[i] = self._task.observation(i, self._rngs[i])
        return self._agent_view(self._obs.copy()), info

    # -- stepping ----------------------------------------------------------------------
    def step(self, actions):
        """One control step of every robot (Gymnasium's VectorEnv.step), the episodes that end reset as the autoreset mode says."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        task = self._task
        a = check_actions(actions, (self.num_envs, 3))
        if self.autoreset_mode == AutoresetMode.DISABLED and self._prev_done.any():
            raise RuntimeError(f"robots {np.flatnonzero(self._prev_done).tolist()} have ended their episodes: reset "
                               "them (reset(options={'reset_mask': ...})) before the next step")
        resetting = self._prev_done.copy() if self.autoreset_mode == AutoresetMode.NEXT_STEP \
            else np.zeros(self.num_envs, dtype=bool)
        self._reset_robots(np.flatnonzero(resetting))
        if self.num_threads > 1:
            numba.set_num_threads(self.num_threads)  # per calling thread; cheap
        task.step_robots(~resetting, a, parallel=self.num_threads > 1)
        outcomes = task.outcomes
        terminated = task.terminated(outcomes)
        truncated = outcomes["episode_steps"] >= self.max_episode_steps
        reward = outcomes["reward"].copy()
        info = task.info()
        reward, terminated, info = self._judge(reward, terminated, info, resetting)
        done = terminated | truncated
        obs = task.observations(self._rngs)
        if self.autoreset_mode == AutoresetMode.SAME_STEP and done.any():
            info["final_obs"] = _masked(self._agent_view(obs), done)
            info["_final_obs"] = done
            info["final_info"] = {k: v for k, v in info.items() if not k.startswith("final")}
            info["_final_info"] = done
            self._reset_robots(np.flatnonzero(done))
            for i in np.flatnonzero(done):
                obs[i] = task.observation(i, self._rngs[i])
        self._prev_done = done
        self._obs = obs
        return self._agent_view(obs.copy()), reward, terminated, truncated, info

    def _reset_robots(self, indices) -> None:
        """Autoreset every robot of ``indices`` or none: each next episode is drawn on a copy of
        its robot's generator before any robot changes (the same draws as on the generator
        itself); a robot whose episode cannot start is named, and no robot is reset.
        """
        drawn = []
        for i in indices:
            rng = copy.deepcopy(self._rngs[i])
            try:
                drawn.append((i, rng, self._task.episode_start(rng, None)))
            except (RuntimeError, ValueError) as error:
                raise RuntimeError(f"autoreset: robot {i}'s next episode cannot start ({error}); no robot of this "
                                   "step was reset") from error
        for i, rng, plan in drawn:
            self._rngs[i] = rng
            self._task.begin_episode(i, plan)

    # -- hooks of the goal-conditioned vector env (scara_gym.envs.goal) -----------------
    def _judge(self, reward: np.ndarray, terminated: np.ndarray, info: dict, resetting: np.ndarray):
        """The step's reward, termination and info (robots in ``resetting`` were reset, not stepped)."""
        return reward, terminated, info

    def _agent_view(self, obs: np.ndarray):
        """The observations as the agents get them, from the task's current robots."""
        return obs


def _masked(obs, done: np.ndarray):
    """obs (an array or a dict of arrays over the robots) where done, 0 elsewhere."""
    if isinstance(obs, dict):
        return {key: _masked(value, done) for key, value in obs.items()}
    return np.where(done[:, None], obs, 0).astype(obs.dtype)
