"""The CUDA backend of the native vector environment: N robots stepped on the GPU.

``gym.make_vec("Scara-C11-v1", num_envs=N, vectorization_mode="vector_entry_point",
device="cuda")``. One thread per robot runs the same compiled step as the CPU vector env
(`scara_gym.envs.cuda_kernels`); observations, rewards, flags and info stay on the
GPU as torch tensors, and torch CUDA tensors are accepted as actions.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from scara_gym.envs.config import EnvConfig, make_config
from scara_gym.envs.core import INFO_FIELDS, N_PARAMS_FLOATS, REWARD_TERMS, STATUS_NO_PLAN
from scara_gym.envs.surface import TaskSurface
from scara_gym.envs.task import RESET_OPTIONS, ScaraTask, check_actions, vector_seeds
from scara_gym.envs.vector import check_autoreset_mode, check_reset_mask
from scara_gym.model import checks, records as R
from scara_gym.model.simulator import SimulationError, failure_message

CUDA_EXTRA = 'pip install "scara_gym[cuda]"'
GPU_EVENT_LOG_SIZE = 1  # the env reads no event log (collisions and reach times are counted), so keep it small
# the packed info's columns after the reward terms (which come first, in REWARD_TERMS order)
INFO_INDEX = {name: k for k, name in enumerate(INFO_FIELDS) if k >= len(REWARD_TERMS)}
TARGET_COLUMNS = slice(R.PARAMS.fields["target"][1] // 8, R.PARAMS.fields["target"][1] // 8 + 3)
FIXED_PLANS = 2**62  # "plans made" of a task whose every episode starts alike: its one plan never runs out


def as_floats(record) -> np.ndarray:
    """A PARAMS record as its N_PARAMS_FLOATS float64 values (every field of PARAMS is float64)."""
    return np.array([record], dtype=R.PARAMS).view(np.float64)


def load_backend():
    """(torch, numba.cuda, the kernels module), or an ImportError/RuntimeError that names what is
    missing: numba-cuda, torch, or a GPU with its driver (``NUMBA_ENABLE_CUDASIM=1`` runs the
    backend on numba's CUDA simulator instead).
    """
    try:
        import torch
    except ImportError:
        raise ImportError(f"device='cuda' returns torch tensors and needs torch: {CUDA_EXTRA} "
                          "(with torch for your CUDA version, see pytorch.org)") from None
    try:
        import numba
        from numba import cuda
    except ImportError:
        raise ImportError(f"device='cuda' needs numba-cuda: {CUDA_EXTRA}") from None
    if not numba.config.ENABLE_CUDASIM:
        try:
            available = cuda.is_available()
        except Exception as error:  # a broken driver or toolkit: say which
            raise RuntimeError(f"device='cuda': numba-cuda cannot use the GPU ({error}); {CUDA_EXTRA} "
                               "installs the CUDA toolkit libraries numba-cuda needs") from None
        if not available:
            raise RuntimeError(
                "device='cuda': no CUDA GPU was found (numba.cuda.is_available() is False: no NVIDIA "
                f"GPU, driver or CUDA libraries; {CUDA_EXTRA} installs the libraries). Use device='cpu', "
                "or set NUMBA_ENABLE_CUDASIM=1 to run the CUDA backend on numba's simulator (slow, for tests)")
    from scara_gym.envs import cuda_kernels
    return torch, cuda, cuda_kernels


class ScaraCudaVectorEnv(TaskSurface, VectorEnv):
    """N copies of a Scara-C11 environment stepped on a CUDA GPU, one thread per robot.

    The arguments are those of `ScaraVectorEnv` (num_envs,
    max_episode_steps, autoreset_mode and the environment's own), plus:

    | argument | meaning | default |
    |---|---|---|
    | plan_depth | episodes drawn ahead per robot (start, target, parameters) | 8 |
    | threads_per_block | CUDA block size of the step kernel | 128 |

    Sub-environment i is the CPU vector env's sub-environment i, bit for bit on numba's CUDA
    simulator (a GPU's fused multiply-adds differ from the CPU's rounding in the last bits).
    ``reset`` and ``step`` return torch tensors on the GPU (on the simulator: on the CPU),
    with the CPU env's dtypes: observations float32, rewards float64, flags bool; info holds
    the same keys as the CPU env's, as tensors. Actions may be a torch tensor (on any
    device) or a numpy array of shape (num_envs, 3).

    Episodes: each robot's coming episodes are drawn on the host from its own generator, in
    the order the CPU env draws them, ``plan_depth`` ahead, and begin on the GPU when the
    previous one ends (autoreset). The host refills a robot's plans when they run low; a task
    whose episodes all start alike (no randomized target or parameters) needs none. With
    ``autoreset_mode="Disabled"`` no robot begins an episode by itself: ``reset(options=
    {"reset_mask": mask})`` begins the masked robots' episodes (drawn on the host as in a full
    reset) and keeps the others' and their last observations, as the CPU vector env does.

    Sim-to-real options: ``action_delay`` and ``action_rate_limit`` act on the device
    (torch) as on the CPU, bit for bit, with ``info["applied_action"]``. ``observation_noise``
    is drawn on the device from a torch generator seeded by ``reset(seed=...)`` (a seed list:
    from all its seeds; no seed: fresh entropy): the same distribution as on the CPU (zero-mean
    Gaussian per entry, then clipped to the observation space), not the same draws, since the
    CPU env draws robot i's noise from robot i's episode generator, which here draws the plans
    ahead. ``sensor_noise`` (derived entries from noisy measurements) is not implemented here and
    is refused with a ValueError, and so is ``randomize_start`` with a delay or a rate limit in
    "pd" mode (the autoreset's neutral action holds the default start). Rendering is not supported.

    Of the state surface (`scara_gym.envs.surface`) it has the configuration (``config``,
    ``params``, ``control_mode`` ...) and the pure set-point maps (``setpoint_to_action``,
    ``action_to_setpoint``). The per-robot methods of the CPU vector env (snapshots, the PD maps
    with a robot's parameters, noise-free observations) are not offered: the robots' states and
    episode parameters live on the device, and reading one robot's costs a transfer per call.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
    config_defaults = EnvConfig()
    """the configuration ``config`` and the keyword overrides start from (a subclass's own)"""

    def __init__(self, num_envs: int = 1, max_episode_steps: int = 300,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 plan_depth: int = 8, threads_per_block: int = 128, config: EnvConfig | None = None,
                 **kwargs) -> None:
        torch, cuda, kernels = load_backend()
        self._torch, self._cuda, self._kernels = torch, cuda, kernels
        self.simulator = kernels.SIMULATOR
        num_envs = checks.integer("num_envs", num_envs, 1, 2**24)
        self.max_episode_steps = checks.integer("max_episode_steps", max_episode_steps, 1, 2**62)
        autoreset_mode = check_autoreset_mode(autoreset_mode)
        self.plan_depth = checks.integer("plan_depth", plan_depth, 2, 1024)
        self.threads_per_block = checks.integer("threads_per_block", threads_per_block, 1, 1024)
        if kwargs.pop("render_mode", None) is not None:
            raise ValueError("the vector environment does not render; use render_mode=None")
        self._task = task = ScaraTask(make_config(config, kwargs, self.config_defaults), num_robots=num_envs)
        self.num_envs = n = num_envs
        self.metadata = {**type(self).metadata, "autoreset_mode": autoreset_mode}
        self.autoreset_mode = autoreset_mode
        self.render_mode = None
        self.device = torch.device("cpu" if self.simulator else "cuda")
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)
        self.single_observation_space = spaces.Box(task.obs_low, task.obs_high, dtype=np.float32)
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self._rngs: list[np.random.Generator | None] = [None] * n
        self.fixed_plans = not (task.randomize_target or task.randomization or task.start_region is not None)
        depth = 1 if self.fixed_plans else self.plan_depth

        # device records: the task's constants, then every robot's state and results
        to_device = cuda.to_device
        self.d_config, self.d_task = to_device(task.step_config), to_device(task.constants)
        self.d_robots = to_device(task.robots)
        self.d_params = to_device(task.robot_params)
        self.d_params_flat = self._flat_view(self.d_params)
        self.d_log = cuda.device_array((n, GPU_EVENT_LOG_SIZE), dtype=R.EVENT)
        self.d_outcomes = to_device(task.outcomes)
        self.d_obs = to_device(task.obs)
        self.d_final_obs = cuda.device_array_like(task.obs)
        self.d_prev_done = to_device(np.zeros(n, dtype=np.bool_))
        self.d_reward = cuda.device_array(n, dtype=np.float64)
        self.d_terminated = cuda.device_array(n, dtype=np.bool_)
        self.d_truncated = cuda.device_array(n, dtype=np.bool_)
        self.d_info = cuda.device_array((n, len(INFO_FIELDS)), dtype=np.float64)
        self.d_flags = cuda.device_array(kernels.N_FLAGS, dtype=np.int64)
        self.d_status = cuda.device_array(n, dtype=np.int64)
        self._flags_start = np.array([0, n, FIXED_PLANS], dtype=np.int64)  # no failure, none failed, plans left
        # episode plans: ring of `depth` per robot, episode e >= 1 in slot e % depth
        self.plans = np.zeros((n, depth, 6))
        self.plan_params = np.zeros((1, 1, N_PARAMS_FLOATS))
        self.varied_params = False
        self.plans_made = np.zeros(n, dtype=np.int64)
        self.d_plans = to_device(self.plans)
        self.d_plan_params = to_device(self.plan_params)
        self.d_plans_made = to_device(self.plans_made)
        self.d_episodes = to_device(np.zeros(n, dtype=np.int64))
        self._blocks = (n + self.threads_per_block - 1) // self.threads_per_block
        self._started = False
        self._ended = None  # "Disabled" autoreset: the robots whose episodes ended and wait for a reset
        self._last_obs = None  # the last observations given (clean, as the agents got them)
        self._goal_threshold = 0.0  # the goal env's episode end where > 0 (scara_gym.envs.goal)

        # sim-to-real, on the device: the actuator's delay line and slew limit, the noise
        options = task.sim_to_real
        self.actuator = TorchActuator(torch, options, n, self.device) if options.shapes_actions else None
        # the neutral action of an episode that starts at the default start (every autoreset one)
        self._neutral = self._neutral_actions(np.tile(task.default_start, (n, 1)))
        if task.start_region is not None and options.shapes_actions and task.control_mode == "pd":
            raise ValueError("randomize_start with action_delay or action_rate_limit in 'pd' mode is not implemented "
                             "on the CUDA vector env (its autoreset holds the default start); use the CPU vector env")
        if options.sensor_noisy:
            raise ValueError("sensor_noise is not implemented on the CUDA vector env (its derived entries would "
                             "need the kinematics on the device); use the CPU vector env or observation_noise")
        self._noise_std = torch.from_numpy(options.noise_std).to(self.device) if options.noisy else None
        self._obs_low = torch.from_numpy(task.obs_low.astype(np.float64)).to(self.device)
        self._obs_high = torch.from_numpy(task.obs_high.astype(np.float64)).to(self.device)
        self._noise_generator = None

    def _flat_view(self, d_params):
        """The PARAMS records as float64 rows, the same memory (every field of PARAMS is float64)."""
        if self.simulator:
            from numba.cuda.simulator.cudadrv.devicearray import FakeCUDAArray
            return FakeCUDAArray(d_params._ary.view(np.float64).reshape(d_params.shape[0], N_PARAMS_FLOATS))
        return d_params.view(np.float64).reshape(d_params.shape[0], N_PARAMS_FLOATS)

    # -- tensors -------------------------------------------------------------------------
    def _tensor(self, d_array):
        """A torch tensor of a device array: a view on the GPU, a host copy on the simulator."""
        torch = self._torch
        if self.simulator:
            return torch.from_numpy(np.ascontiguousarray(d_array.copy_to_host()))
        return torch.as_tensor(d_array, device=self.device)

    def _device_actions(self, actions):
        """Checked float64 actions as a torch tensor on the device (finite, shape (num_envs, 3))."""
        torch = self._torch
        shape = (self.num_envs, 3)
        if isinstance(actions, torch.Tensor):
            if actions.is_complex() or actions.dtype == torch.bool:
                raise ValueError(f"action must hold real numbers, got a tensor of {actions.dtype}")
            if tuple(actions.shape) != shape:
                raise ValueError(f"action must have shape {shape}, got {tuple(actions.shape)}")
            if not self.simulator and actions.device.type == "cuda":
                actions = actions.detach().to(device=self.device, dtype=torch.float64).contiguous()
                if not bool(torch.isfinite(actions).all()):
                    check_actions(actions.cpu().numpy(), shape)  # raises naming the value
                return actions
            actions = actions.detach().cpu().numpy()
        return torch.from_numpy(check_actions(actions, shape)).to(self.device)

    def _numba_array(self, tensor):
        """A torch tensor of the device as a numba device array (a view on the GPU)."""
        if self.simulator:
            return self._cuda.to_device(np.ascontiguousarray(tensor.numpy()))
        return self._cuda.as_cuda_array(tensor.contiguous())

    def _targets(self):
        """Every robot's target q^ [rad, rad, m] (float64 tensor, a copy)."""
        return self._tensor(self.d_params_flat)[:, TARGET_COLUMNS].clone()

    def _neutral_actions(self, starts: np.ndarray):
        """The actions of robots at rest at ``starts``: their set-points in "pd" mode, zero volts
        in "voltage" mode (the actuator's state before an episode), as a tensor.
        """
        task = self._task
        neutral = np.array([task.setpoint_to_action(start) for start in starts]) if task.control_mode == "pd" \
            else np.zeros((len(starts), 3))
        return self._torch.from_numpy(neutral).to(self.device)

    def _noisy(self, obs):
        """Observations as the agents get them: with the observation noise, where configured."""
        if self._noise_std is None:
            return obs
        torch = self._torch
        noise = torch.randn(obs.shape, generator=self._noise_generator, dtype=torch.float64, device=self.device)
        noisy = obs.to(torch.float64) + noise * self._noise_std
        return torch.minimum(torch.maximum(noisy, self._obs_low), self._obs_high).to(torch.float32)

    def _seed_noise(self, seeds: list[int | None]) -> None:
        if self._noise_std is None or (self._noise_generator is not None and all(s is None for s in seeds)):
            return
        given = [s for s in seeds if s is not None]
        entropy = np.random.SeedSequence(given if given else None).generate_state(2, np.uint32)
        self._noise_generator = self._torch.Generator(device=self.device)
        self._noise_generator.manual_seed(int(entropy[0]) << 31 | int(entropy[1]) >> 1)

    # -- episodes ------------------------------------------------------------------------
    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Start every robot's episode (Gymnasium's VectorEnv.reset); seed: one, or one per robot."""
        seeds = vector_seeds(seed, self.num_envs)
        options = checks.mapping("reset options", options, (*RESET_OPTIONS, "reset_mask"))
        mask = check_reset_mask(options, self.num_envs, self.autoreset_mode)
        if mask is not None:
            return self._reset_masked(mask, seeds, options)
        task, n = self._task, self.num_envs
        if self.fixed_plans and not options:  # every episode starts alike: no draws, nothing per robot
            plans = [task.episode_start(None, None)] * n
        else:
            rngs = [self._rng(i) if s is None else seeding.np_random(s)[0] for i, s in enumerate(seeds)]
            plans = [task.episode_start(rng, options) for rng in rngs]  # all checked before any change
            self._rngs = rngs
        for i, plan in enumerate(plans):
            task.use_params(i, plan.params)
        self._seed_noise(seeds)
        starts = np.array([plan.start for plan in plans])
        targets = np.array([plan.target for plan in plans])
        self.d_params.copy_to_device(task.robot_params)
        self._kernels.begin_kernel[self._blocks, self.threads_per_block](
            self._cuda.to_device(np.ones(n, dtype=np.bool_)), self._cuda.to_device(starts), self._cuda.to_device(targets),
            self.d_robots, self.d_params, self.d_config, self.d_task, self.d_outcomes, self.d_obs)
        self.d_prev_done.copy_to_device(np.zeros(n, dtype=np.bool_))
        self.d_episodes.copy_to_device(np.zeros(n, dtype=np.int64))
        # parameters travel with the plans where they vary: drawn, or overridden for this episode
        # only (then the next episodes go back to the nominal ones)
        self.varied_params = bool(task.randomization) or "params" in options
        depth = self.plans.shape[1]
        shape = (n, depth, N_PARAMS_FLOATS) if self.varied_params else (1, 1, N_PARAMS_FLOATS)
        if self.plan_params.shape != shape:
            self.plan_params = np.zeros(shape)
            self.d_plan_params = self._cuda.to_device(self.plan_params)
        if self.fixed_plans:
            self.plans[:, 0, :3], self.plans[:, 0, 3:] = task.default_start, task.default_target
            self.plan_params[:, 0] = as_floats(task.nominal_record)
            self.plans_made[:] = FIXED_PLANS
        else:
            self.plans_made[:] = 0
            self._refill(np.arange(n), np.zeros(n, dtype=np.int64))
        self._upload_plans()
        if self.actuator is not None:
            self.actuator.reset(self._torch.ones(n, dtype=self._torch.bool, device=self.device),
                                self._neutral_actions(starts))
        self._started = True
        info = {"target": self._torch.from_numpy(targets).to(self.device)}
        varied = sorted({path for plan in plans for path in plan.varied})
        if varied:
            info["params"] = {path: self._torch.tensor([plan.varied.get(path, np.nan) for plan in plans],
                                                       dtype=self._torch.float64, device=self.device)
                              for path in varied}
        obs = self._tensor(self.d_obs).clone()
        self._ended = self._torch.zeros(n, dtype=self._torch.bool, device=self.device)
        self._last_obs = (self._noisy(obs), obs)
        return self._agent_view(*self._last_obs, self._targets()), info

    def _reset_masked(self, mask: np.ndarray, seeds: list[int | None], options: dict):
        """reset(options={"reset_mask": mask}) in "Disabled" autoreset mode: the robots of ``mask``
        begin episodes (each drawn as in a full reset, from its seed or its own generator), the
        others keep their episodes and their last observations.
        """
        if not self._started:
            raise RuntimeError("options['reset_mask']: call reset() without a mask first (no robot has begun)")
        torch, task, n = self._torch, self._task, self.num_envs
        robots = np.flatnonzero(mask)
        rngs = {i: self._rng(i) if seeds[i] is None else seeding.np_random(seeds[i])[0] for i in robots}
        plans = {i: task.episode_start(rng, options) for i, rng in rngs.items()}  # all checked before any change
        for i, plan in plans.items():
            self._rngs[i] = rngs[i]
            task.use_params(i, plan.params)
        self._seed_noise([s if m else None for s, m in zip(seeds, mask)])
        starts, targets = np.zeros((n, 3)), np.zeros((n, 3))
        for i, plan in plans.items():
            starts[i], targets[i] = plan.start, plan.target
        # the reset robots' parameter records, the others' as the device holds them (their targets
        # live there: begin_kernel writes them)
        records = self.d_params.copy_to_host()
        records[mask] = task.robot_params[mask]
        self.d_params.copy_to_device(records)
        self._kernels.begin_kernel[self._blocks, self.threads_per_block](
            self._cuda.to_device(mask), self._cuda.to_device(starts), self._cuda.to_device(targets), self.d_robots,
            self.d_params, self.d_config, self.d_task, self.d_outcomes, self.d_obs)
        prev_done = self.d_prev_done.copy_to_host()
        prev_done[mask] = False
        self.d_prev_done.copy_to_device(prev_done)
        rows = torch.from_numpy(mask).to(self.device)
        if self.actuator is not None:
            self.actuator.reset(rows, self._neutral_actions(starts))
        self._ended = self._ended & ~rows
        clean = self._tensor(self.d_obs).clone()
        noisy_before, clean_before = self._last_obs
        self._last_obs = (torch.where(rows[:, None], self._noisy(clean), noisy_before),
                          torch.where(rows[:, None], clean, clean_before))
        info = {"target": self._targets(), "_target": rows}
        varied = sorted({path for plan in plans.values() for path in plan.varied})
        if varied:
            info["params"] = {path: torch.tensor([plans[i].varied.get(path, np.nan) if i in plans else np.nan
                                                  for i in range(n)], dtype=torch.float64, device=self.device)
                              for path in varied}
        return self._agent_view(*self._last_obs, self._targets()), info

    def _rng(self, i: int) -> np.random.Generator:
        """Robot i's episode generator (made on first use: a task without draws needs none)."""
        if self._rngs[i] is None:
            self._rngs[i] = seeding.np_random(None)[0]
        return self._rngs[i]

    def _refill(self, rows: np.ndarray, episodes: np.ndarray) -> None:
        """Draw plans for robots `rows` (at episodes `episodes`) until each holds plan_depth - 1 ahead."""
        depth = self.plans.shape[1]
        task = self._task
        for i, episode in zip(rows, episodes[rows]):
            while self.plans_made[i] < episode + depth - 1:
                e = self.plans_made[i] + 1
                plan = task.episode_start(self._rng(i), None)
                self.plans[i, e % depth, :3], self.plans[i, e % depth, 3:] = plan.start, plan.target
                if self.varied_params:
                    self.plan_params[i, e % depth] = as_floats(task.params_record(plan.params))
                self.plans_made[i] = e

    def _upload_plans(self) -> None:
        self.d_plans.copy_to_device(self.plans)
        self.d_plan_params.copy_to_device(self.plan_params)
        self.d_plans_made.copy_to_device(self.plans_made)

    # -- stepping ------------------------------------------------------------------------
    def step(self, actions):
        """One control step of every robot (Gymnasium's VectorEnv.step), the episodes that end reset as the autoreset mode says."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        torch, kernels = self._torch, self._kernels
        n = self.num_envs
        given = self._device_actions(actions)
        disabled = self.autoreset_mode == AutoresetMode.DISABLED
        if disabled and bool(self._ended.any()):  # one synchronizing read, in this mode only
            raise RuntimeError(f"robots {torch.nonzero(self._ended).flatten().tolist()} have ended their episodes: "
                               "reset them (reset(options={'reset_mask': ...})) before the next step")
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        # robots that begin an episode instead of stepping (NextStep autoreset): only the
        # actuator and the goal rules need them, so the plain env's hot path reads nothing
        resetting = None
        if self.actuator is not None or self._goal_threshold > 0.0:
            resetting = torch.zeros(n, dtype=torch.bool, device=self.device) if same_step \
                else self._tensor(self.d_prev_done).clone()
        applied = given
        if self.actuator is not None:  # the delay line and the slew limit see the clipped action
            clipped_given = (given.abs() > 1.0).sum(dim=1)
            applied = self.actuator.apply(given.clamp(-1.0, 1.0))
        targets_before = self._targets() if self._goal_threshold > 0.0 else None
        d_actions = self._numba_array(applied)
        self.d_flags.copy_to_device(self._flags_start)
        kernels.step_kernel[self._blocks, self.threads_per_block](
            same_step, self.max_episode_steps, self._task.collision_mode == "terminate", self._goal_threshold,
            d_actions, self.d_robots, self.d_params, self.d_params_flat, self.d_config, self.d_task, self.d_log,
            self.d_outcomes, self.d_obs, self.d_prev_done, self.d_plans, self.d_plan_params, self.varied_params,
            self.d_plans_made, self.d_episodes, self.d_reward, self.d_terminated, self.d_truncated, self.d_final_obs,
            self.d_info, self.d_status, self.d_flags)
        failures, first_failed, plans_left = self.d_flags.copy_to_host()  # the one synchronizing copy
        if failures:
            self._raise_for(int(first_failed), d_actions)
        low_water = self.plans.shape[1] // 2
        if not self.fixed_plans and plans_left <= low_water:
            episodes = self.d_episodes.copy_to_host()
            low = np.flatnonzero(self.plans_made - episodes <= low_water)
            self._refill(low, episodes)
            self._upload_plans()

        obs = self._tensor(self.d_obs).clone()
        reward = self._tensor(self.d_reward).clone()
        terminated = self._tensor(self.d_terminated).clone()
        truncated = self._tensor(self.d_truncated).clone()
        info = self._info(self._tensor(self.d_info))
        done = terminated | truncated
        final = self._tensor(self.d_final_obs) if same_step and bool(done.any()) else None
        if self.actuator is not None:
            stepped = ~resetting
            info["clipped_actions"] = torch.where(stepped, clipped_given, info["clipped_actions"])
            self.actuator.reset(resetting, self._neutral)  # as the CPU env: before the step's info
            info["applied_action"] = self.actuator.applied.clone()
            if same_step:
                self.actuator.reset(done, self._neutral)  # the next episodes: after it
        if self._goal_threshold > 0.0:
            clean = obs if final is None else torch.where(done[:, None], final, obs)
            reward, info = self._judge(clean, targets_before, info, ~resetting)
        noisy = self._noisy(obs)
        if disabled:  # what a masked reset keeps for the robots it leaves alone
            self._ended, self._last_obs = done, (noisy, obs)
        view = self._agent_view(noisy, obs, self._targets() if self._goal_threshold > 0.0 else None)
        if final is not None:
            final_view = self._agent_view(self._noisy(final), final, targets_before)
            info["final_obs"] = _masked(torch, final_view, done)
            info["_final_obs"] = done
            info["final_info"] = {k: v for k, v in info.items() if not k.startswith("final")}
            info["_final_info"] = done
        return view, reward, terminated, truncated, info

    # -- hooks of the goal-conditioned env (scara_gym.envs.goal) -------------------------
    def _agent_view(self, obs, clean_obs, targets):
        """The observations as the agents get them (obs: with noise; clean_obs: without)."""
        return obs

    def _judge(self, clean_obs, targets, info, stepped):
        """The goal env's reward and info of a step, from the true observations at its end and
        the targets it ran to (only where _goal_threshold > 0).
        """
        raise NotImplementedError

    def _info(self, packed) -> dict:
        """The CPU vector env's info entries from the packed info rows (INFO_FIELDS)."""
        torch = self._torch
        column = {name: packed[:, k] for name, k in INFO_INDEX.items()}
        reached = column["reached"] != 0.0
        collided = column["collisions"] > 0.0
        return {
            "reward_terms": {term: packed[:, k].clone() for k, term in enumerate(REWARD_TERMS)},
            "is_success": reached,
            "cost": collided.to(torch.float64),
            "collision": collided,
            "collisions": column["episode_collisions"].to(torch.int64),
            "critical": column["critical"] == 1.0,
            "time": column["time"].clone(),
            "energy": column["energy"].clone(),
            "clipped_actions": column["clipped"].to(torch.int64),
            "reach_time": torch.where(reached, column["reach_time"], torch.full_like(column["reach_time"], np.nan)),
            "_reach_time": reached,
        }

    def _raise_for(self, i: int, d_actions) -> None:
        robot = self.d_robots[i:i + 1].copy_to_host()[0]
        status = int(self.d_status[i:i + 1].copy_to_host()[0])
        if status == R.STATUS_BAD_ACTION:
            check_actions(d_actions[i:i + 1].copy_to_host()[0], (3,))
        if status == STATUS_NO_PLAN:
            raise RuntimeError(f"sub-environment {i} ran out of episode plans (a bug: the host refills them)")
        raise SimulationError(f"sub-environment {i}: "
                              + failure_message(status, robot, self._task.step_config[0], self._task.params))

    # -- host views (copies), for tests and inspection -----------------------------------
    @property
    def targets(self) -> np.ndarray:
        """The robots' targets q^ [rad, rad, m], shape (num_envs, 3) (a host copy)."""
        return self.d_params.copy_to_host()["target"]


def _masked(torch, obs, done):
    """obs (a tensor or a dict of them over the robots) where done, 0 elsewhere."""
    if isinstance(obs, dict):
        return {key: _masked(torch, value, done) for key, value in obs.items()}
    return torch.where(done[:, None], obs, torch.zeros_like(obs))


class TorchActuator:
    """`scara_gym.envs.sim_to_real.Actuator` on torch tensors: the same operations in
    the same order, so the same bits.
    """

    def __init__(self, torch, options, num_robots: int, device) -> None:
        self.torch = torch
        self.pending = torch.zeros((num_robots, options.action_delay, 3), dtype=torch.float64, device=device)
        """actions given and not yet applied, oldest first"""
        self.applied = torch.zeros((num_robots, 3), dtype=torch.float64, device=device)
        """the action applied in each robot's last step"""
        rate = options.action_rate_limit
        self.max_change = None if rate is None else rate * options.control_dt

    def reset(self, rows, neutral) -> None:
        """The robots where ``rows`` (a bool tensor) begin an episode: the line full of their
        neutral action (``neutral``: one row per robot), the output at it.
        """
        rows = rows[:, None]
        self.pending = self.torch.where(rows[:, :, None], neutral[:, None, :], self.pending)
        self.applied = self.torch.where(rows, neutral, self.applied)

    def apply(self, actions):
        """The actions every robot applies this step, given ``actions`` (clipped to [-1, 1]);
        advances the delay lines.
        """
        torch = self.torch
        out = actions
        if self.pending.shape[1]:
            out = self.pending[:, 0].clone()
            self.pending = torch.cat([self.pending[:, 1:], actions[:, None]], dim=1)
        if self.max_change is not None:
            out = self.applied + (out - self.applied).clamp(-self.max_change, self.max_change)
        self.applied = out
        return out
