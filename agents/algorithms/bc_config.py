"""The behaviour cloning's typed configuration (torch-free, so that the run registry and the
command line can read and check it without importing torch)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from agents.algorithms.torch_ppo_config import SEED_MAX
from scara_gym.model import checks
from scara_gym.model.checks import UserError


@dataclass
class BCConfig:
    """One behaviour-cloning run."""

    dataset: str = "scara/c11/expert-v0"  # a Minari dataset id (in Minari's data folder)
    seed: int = 0
    hidden_size: int = 256
    layers: int = 2
    learning_rate: float = 1e-3
    batch_size: int = 256
    steps: int = 20_000          # Adam steps
    residual_scale: tuple[float, float, float] | None = None  # clone in the residual set-point's space
    residual_deadzone: float = 0.5  # (scara_gym.wrappers.residual), as the engineered PPO agents act
    torch_threads: int = 1
    out: str = "runs/bc"

    def __post_init__(self) -> None:
        if not isinstance(self.dataset, str) or not self.dataset:
            raise UserError(f"dataset must be a Minari dataset id, got {self.dataset!r}")
        checks.integer("seed", self.seed, 0, SEED_MAX)
        checks.integer("torch_threads", self.torch_threads, 0, None)
        for name in ("hidden_size", "layers", "batch_size", "steps"):
            checks.integer(name, getattr(self, name), 1, None)
        checks.real("learning_rate", self.learning_rate, 0.0, 1.0, low_open=True)
        if self.residual_scale is not None:
            self.residual_scale = tuple(float(x) for x in checks.real_array(
                "residual_scale", self.residual_scale, (3,), low=1e-12, high=1e6, range_text="every entry > 0"))
        checks.real("residual_deadzone", self.residual_deadzone, 0.0, 1.0)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)
