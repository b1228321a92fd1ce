"""The single-file PPO's typed configuration (torch-free, so that the command line and the run
registry can read and check it without importing torch)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from scara_gym.benchmark.protocol import ENV_ID
from scara_gym.envs.randomization import PRESETS
from scara_gym.envs.task import MAX_ROBOTS
from scara_gym.model import checks
from scara_gym.model.checks import UserError, UserTypeError
from scara_gym.registration import ENV_IDS
from scara_gym.wrappers.residual import RESIDUAL_ON

INF = float("inf")
SEED_MAX = 2**32 - 1
"""the largest seed a run takes (torch's, numpy's and the vector env's seeding, seed + robot, stay in range)"""


@dataclass
class Config:
    """One run of the single-file PPO (every field a command-line flag of ``scara-agents torch-ppo``)."""

    env_id: str = ENV_ID
    control_mode: str = "pd"
    randomize_target: bool = False
    randomize_params: str | None = None  # domain randomization per episode: a preset of scara_gym.envs.randomization
    randomize_start: bool = False  # starts drawn per episode from the protocol's start region
    sensor_noise: float = 0.0      # noisy sensors at this multiple of the protocol's SENSOR_NOISE levels
    reward_weights: dict[str, float] = field(default_factory=dict)  # env reward weights to change (none: the env's)
    residual_scale: tuple[float, float, float] | None = None  # act through a residual set-point around the target
    residual_deadzone: float = 0.2  # (scara_gym.wrappers.residual: an engineered agent, not plain PPO)
    residual_on: str = "setpoint"  # the residual's base: "setpoint" (around the target) or "pd" (the PD law's voltages)
    device: str = "cpu"            # where the env runs and the agent trains: "cpu" or "cuda"
    seed: int = 0
    num_envs: int = 16
    num_steps: int = 128           # rollout length per env; a batch is num_envs * num_steps
    total_timesteps: int = 1_000_000
    learning_rate: float = 3e-4
    anneal_lr: bool = True
    gamma: float = 0.99
    gae_lambda: float = 0.95
    num_minibatches: int = 32
    update_epochs: int = 10
    clip_coef: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden_size: int = 64
    normalize_reward: bool = True  # scale rewards by the running std of the discounted return
    clip_obs: float = 10.0
    env_threads: int = 1           # numba threads of the CPU env (torch takes the cores between steps)
    # torch's threads: 1 per run. Its minibatches are tiny (2,048 / 32 samples), so more threads
    # only add synchronization, and torch's default (one per core) collapses as soon as another
    # process wants a core: on 2 cores 252 against 7,192 steps/s (docs/experiments.md, 2026-12-05).
    # 0: torch's default.
    torch_threads: int = 1
    compile: bool = False          # torch.compile the minibatch gradient
    checkpoint_every: int = 10     # updates between checkpoints
    init_log_std: float = 0.0      # the policy's initial log standard deviation
    init_from: str | None = None   # a finished run of this file to start from (its model.pt), e.g. to fine-tune
    # research add-ons, read by agents.algorithms.torch_ppo_hooks.hooks_for (plain PPO: all off)
    demo_resets: float = 0.0       # share of training episodes that start on the optimal reference's path
    demo_wall_margin: float = 1e-3 # m, the wall margin of that reference (a shipped optimal solution)
    target_replay: float = 0.0     # share of training episodes given a target the agent recently failed
    shield: bool = False           # act behind scara_gym.wrappers.Shield, in training and evaluation
    demo_bc: float = 0.0           # weight of the behaviour-cloning term on the optimal reference's steps
    demo_bc_decay: float = 1.0     # that weight's factor per update (DAPG's decay)
    demo_bc_pretrain: int = 0      # Adam steps on the cloning term alone before the first rollout
    cost_limit: float | None = None  # PPO-Lagrangian: the episode cost (info["cost"]) allowed; None: off
    lagrange_lr: float = 0.05      # its multiplier's step per rollout per unit of excess episode cost
    lagrange_init: float = 0.0     # its multiplier's start
    out: str = "runs/torch_ppo"

    def __post_init__(self) -> None:
        """Every field checked before anything starts: a mistake names the field and what it allows."""
        checks.choice("env_id", self.env_id, ENV_IDS)
        checks.choice("control_mode", self.control_mode, ("pd", "voltage"))
        checks.choice("device", self.device, ("cpu", "cuda"))
        checks.choice("residual_on", self.residual_on, RESIDUAL_ON)
        if self.residual_on == "pd" and self.control_mode != "voltage":
            raise UserError("residual_on='pd' corrects the PD law's voltages: it needs control_mode='voltage'")
        for name in ("randomize_target", "randomize_start", "anneal_lr", "normalize_reward", "compile", "shield"):
            checks.flag(name, getattr(self, name))
        if self.randomize_params is not None:
            checks.choice("randomize_params", self.randomize_params, sorted(PRESETS))
        if not isinstance(self.reward_weights, dict):
            raise UserTypeError(f"reward_weights must be a dict of name -> number, got {self.reward_weights!r}")
        for name, value in self.reward_weights.items():
            checks.real(f"reward_weights[{name!r}]", value)
        if self.residual_scale is not None:
            self.residual_scale = tuple(float(x) for x in checks.real_array(
                "residual_scale", self.residual_scale, (3,), low=1e-12, high=1e6, range_text="every entry > 0"))
        for name, low, high in (("seed", 0, SEED_MAX), ("num_envs", 1, MAX_ROBOTS), ("num_steps", 1, None),
                                ("total_timesteps", 1, None), ("num_minibatches", 1, None), ("update_epochs", 1, None),
                                ("hidden_size", 1, None), ("env_threads", 1, None), ("torch_threads", 0, None),
                                ("checkpoint_every", 1, None), ("demo_bc_pretrain", 0, None)):
            checks.integer(name, getattr(self, name), low, high)
        if self.batch_size % self.num_minibatches:
            raise UserError(f"num_minibatches must divide the batch num_envs * num_steps = {self.batch_size}, "
                            f"got {self.num_minibatches}")
        for name, low, high, low_open in (
                ("learning_rate", 0.0, 1.0, False), ("gamma", 0.0, 1.0, True), ("gae_lambda", 0.0, 1.0, True),
                ("clip_coef", 0.0, INF, True), ("ent_coef", 0.0, INF, False), ("vf_coef", 0.0, INF, False),
                ("max_grad_norm", 0.0, INF, True), ("clip_obs", 0.0, INF, True), ("init_log_std", -20.0, 5.0, False),
                ("sensor_noise", 0.0, 1e3, False), ("residual_deadzone", 0.0, 1.0, False),
                ("demo_resets", 0.0, 1.0, False), ("demo_wall_margin", 0.0, 0.05, False),
                ("target_replay", 0.0, 1.0, False), ("demo_bc", 0.0, INF, False), ("demo_bc_decay", 0.0, 1.0, True),
                ("lagrange_lr", 0.0, 1e3, True), ("lagrange_init", 0.0, 1e6, False)):
            checks.real(name, getattr(self, name), low, high, low_open=low_open)
        if self.cost_limit is not None:
            checks.real("cost_limit", self.cost_limit, 0.0, 1e6)
        if not isinstance(self.out, str) or not self.out:
            raise UserError(f"out must be a folder path, got {self.out!r}")

    @property
    def batch_size(self) -> int:
        return self.num_envs * self.num_steps

    @property
    def minibatch_size(self) -> int:
        return self.batch_size // self.num_minibatches

    def to_dict(self) -> dict:
        """The run's record in config.json (JSON types: the tuple as a list)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, record: dict) -> Config:
        """A Config from a run's config.json (its other entries ignored). Runs written before the
        fields were typed hold reward_weights as "name=value,..." and residual_scale as "a,b,c"
        ("" for none), and "" for no randomize_params or init_from: those are read too."""
        known = {f.name for f in dataclasses.fields(cls)}
        values = {k: v for k, v in record.items() if k in known}
        if isinstance(values.get("reward_weights"), str):
            values["reward_weights"] = parse_reward_weights(values["reward_weights"])
        if isinstance(values.get("residual_scale"), str):
            values["residual_scale"] = parse_floats("residual_scale", values["residual_scale"], 3) \
                if values["residual_scale"] else None
        elif values.get("residual_scale") is not None:
            values["residual_scale"] = tuple(float(x) for x in values["residual_scale"])
        for name in ("randomize_params", "init_from"):
            if values.get(name) == "":
                values[name] = None
        return cls(**values)


def parse_reward_weights(text: str) -> dict[str, float]:
    """ "energy=0.05,time=20" -> {"energy": 0.05, "time": 20.0} (the env checks the names)."""
    weights = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        name, _, value = item.partition("=")
        try:
            weights[name.strip()] = float(value)
        except ValueError:
            raise UserError(f"reward_weights: expected name=number items separated by commas, got {item!r}") from None
    return weights


def parse_floats(name: str, text: str, count: int) -> tuple[float, ...]:
    """ "2.5,2.5,0.05" -> (2.5, 2.5, 0.05), exactly ``count`` numbers."""
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        values = ()
    if len(values) != count:
        raise UserError(f"{name}: expected {count} numbers separated by commas, got {text!r}")
    return values
