"""DAgger's typed configuration (torch-free, so that the run registry and the command line can read
and check it without importing torch)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from scara_gym.benchmark.protocol import CONDITIONS, ENV_ID
from scara_gym.model import checks
from scara_gym.model.checks import UserError
from scara_gym.registration import ENV_IDS
from scara_gym.wrappers.residual import RESIDUAL_ON

DAGGER_SEED = 30_000_000
"""the first seed of DAgger's training episodes: run seed s, iteration i, episode k reset from
DAGGER_SEED + s 10^5 + i 10^3 + k (seed < 100, iteration < 100, episodes < 1,000), below the
datasets' seeds (60M on) and the protocol's tuning (10^8) and evaluation (10^9) seeds"""


@dataclass
class DAggerConfig:
    """One DAgger run: a network distilled from an expert at the states the network itself visits."""

    expert: str = "mpc-rti"        # the expert's policy spec (agents.algorithms.loaders), in control_mode
    conditions: tuple[str, ...] = ("c11-starts", "random-targets", "random-shifts")  # the training draws
    env_id: str = ENV_ID
    control_mode: str = "pd"
    residual_scale: tuple[float, float, float] | None = (2.5, 2.5, 0.05)  # the network's outputs are residuals
    residual_deadzone: float = 0.5  # (scara_gym.wrappers.residual), as the behaviour cloning's
    residual_on: str = "setpoint"   # "setpoint" ("pd" mode) or "pd" (the PD law's voltages, "voltage" mode)
    iterations: int = 10            # at most; fewer where the tuning gap stops shrinking (patience)
    episodes_per_iteration: int = 30  # shared out over the conditions, in turn
    beta: float = 0.5               # iteration i acts with the expert at each step with probability beta^i
    patience: int = 3               # stop after this many iterations without a smaller tuning gap
    tuning_episodes: int = 10       # per condition, on its tuning set: the network alone, every iteration
    seed: int = 0
    hidden_size: int = 256
    layers: int = 2
    learning_rate: float = 1e-3
    batch_size: int = 256
    steps_per_iteration: int = 5_000  # Adam steps on the whole aggregate, continuing the last weights
    torch_threads: int = 1
    out: str = "runs/dagger"

    def __post_init__(self) -> None:
        if not isinstance(self.expert, str) or not self.expert:
            raise UserError(f"expert must be a policy spec (e.g. 'mpc-rti'), got {self.expert!r}")
        self.conditions = tuple(self.conditions)
        if not self.conditions:
            raise UserError("conditions must name at least one of the protocol's conditions")
        for name in self.conditions:
            checks.choice("conditions", name, tuple(CONDITIONS))
        checks.choice("env_id", self.env_id, tuple(ENV_IDS))
        checks.choice("control_mode", self.control_mode, ("pd", "voltage"))
        checks.choice("residual_on", self.residual_on, RESIDUAL_ON)
        if self.residual_scale is not None:
            self.residual_scale = tuple(float(x) for x in checks.real_array(
                "residual_scale", self.residual_scale, (3,), low=1e-12, high=1e6, range_text="every entry > 0"))
        if (self.residual_on == "pd") != (self.control_mode == "voltage") and self.residual_scale is not None:
            raise UserError(f"residual_on {self.residual_on!r} goes with control_mode "
                            f"{'voltage' if self.residual_on == 'pd' else 'pd'!r}, got {self.control_mode!r}")
        checks.real("residual_deadzone", self.residual_deadzone, 0.0, 1.0, high_open=True)
        checks.integer("seed", self.seed, 0, 99)
        checks.integer("iterations", self.iterations, 1, 99)
        checks.integer("episodes_per_iteration", self.episodes_per_iteration, 1, 999)
        checks.real("beta", self.beta, 0.0, 1.0)
        checks.integer("patience", self.patience, 1, None)
        checks.integer("tuning_episodes", self.tuning_episodes, 1, 10**4)
        checks.integer("torch_threads", self.torch_threads, 0, None)
        for name in ("hidden_size", "layers", "batch_size", "steps_per_iteration"):
            checks.integer(name, getattr(self, name), 1, None)
        checks.real("learning_rate", self.learning_rate, 0.0, 1.0, low_open=True)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> DAggerConfig:
        """A config from a record that may hold more than its fields (a run's config.json)."""
        return cls(**{k: v for k, v in values.items() if k in cls.__dataclass_fields__})
