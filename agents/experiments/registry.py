"""The run registry: what every named training run of the project is.

One table, `RUNS`, keyed by the run's name (the folder name under
``RUNS/ENV_ID/MODE/NAME/seedN``): which trainer it uses, its hyperparameters (a YAML block of
`agents.algorithms.sb3.hyperparams`, or the torch PPO ``Config`` fields it changes), the
run a fine-tune starts from, and tags. Training, the campaign, the comparison, the sweeps and
the acceptance targets read these entries and their tags; none parses a name. How each
variant came about, and its pilots, is in ``docs/experiments.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

from scara_gym.benchmark.protocol import CONDITIONS
from scara_gym.model.checks import UserError

TAGS = {
    "standard": "a standard algorithm on the environment as users get it (its own reward and actions)",
    "engineered": "an engineered agent: a shaped training reward and/or a residual set-point",
    "residual": "acts through a residual map of scara_gym.wrappers.residual (a set-point around the target, or a "
                "correction of the PD law's voltages)",
    "random-targets": "trained for targets drawn per episode",
    "domain-randomized": "trained with physics and wall drawn per episode (the robustness target's agents)",
    "energy-aware": "an energy cost in its training reward",
    "shielded": "trained and evaluated behind scara_gym.wrappers.Shield",
    "also-shielded": "the comparison also evaluates it behind the shield, by default",
    "fine-tune": "starts from the same seed's finished run of its base entry",
    "demonstrations": "learns from the optimal reference's path (reset states or behaviour cloning)",
    "perturbed-starts": "trained from starts drawn in the protocol's start region (randomize_start)",
    "sensor-noise": "trained with noisy sensors (sensor_noise at the protocol's levels)",
    "offline": "learns from an offline dataset (agents.experiments.datasets) without acting in the env: its own kind",
    "learning-curve": "trained to a large budget with checkpoints along the way: scara-agents learning-curve scores them",
    "pilot": "a pilot, not a baseline: trained and logged (docs/experiments.md), left out of the comparison's tables",
    "interface-ablation": "one of three runs that differ only in the action interface (absolute set-point, "
                          "set-point relative to the target, residual on the PD law's voltages)",
    "distilled": "distilled from an expert by DAgger at the states the network itself visits "
                 "(agents.algorithms.dagger; the expert: the real-time MPC)",
    "tuned": "its recipe is the best trial of the hyperparameter search (agents.experiments.search), whose "
             "record is published under results/search/",
    "gsde": "explores with generalized state-dependent exploration (gSDE: noise from a state-dependent "
            "map resampled every sde_sample_freq steps, use_sde on); searched on its own (its search keeps "
            "use_sde on)",
    "constrained": "PPO-Lagrangian: the episode's collision cost held to cost_limit by a multiplier learned beside "
                   "the policy (agents.algorithms.torch_ppo_hooks.Lagrangian)",
}
"""every tag a run may carry, and what it says"""


TRAINING_DRAWS = {"perturbed-starts": "c11-starts", "random-targets": "random-targets",
                  "domain-randomized": "random-shifts"}
"""tag -> the protocol condition whose draws a run with that tag trained on. In these three conditions
a learned row whose run trained on other draws is *zero-shot*: it measures transfer, not learning
(issue 58 item 5), and the headline leaves it out (agents.experiments.entries.is_zero_shot)."""


def trained_for(tags) -> frozenset[str]:
    """The conditions of TRAINING_DRAWS whose draws a run with ``tags`` trained on."""
    return frozenset(condition for tag, condition in TRAINING_DRAWS.items() if tag in tags)


def zero_shot(tags, condition: str) -> bool:
    """Whether a run with ``tags`` scored in ``condition`` is zero-shot there: the condition is one
    of the training distributions (TRAINING_DRAWS) and the run never trained on its draws."""
    return condition in TRAINING_DRAWS.values() and condition not in trained_for(tags)


TRAINERS = ("sb3", "torch-ppo", "bc", "dagger")
"""the trainers a run may name"""


@dataclass(frozen=True)
class RunSpec:
    """One registered training run (its seeds are given when it is trained)."""

    name: str
    trainer: str
    """"sb3" (agents.algorithms.sb3.training), "torch-ppo" (agents.algorithms.torch_ppo), "bc"
    (agents.algorithms.bc: behaviour cloning of ``dataset``) or "dagger" (agents.algorithms.dagger)"""
    description: str
    sb3_algorithm: str | None = None
    """SB3's algorithm class: "ppo", "sac", "td3" or "tqc" (trainer "sb3")"""
    recipe: str | None = None
    """the hyperparameter file (agents.algorithms.sb3.hyperparams.FILES; trainer "sb3")"""
    variant: str | None = None
    """the YAML block "MODE-VARIANT" instead of "MODE" (trainer "sb3")"""
    fields: dict = field(default_factory=dict)
    """torch PPO Config fields changed from the defaults (trainer "torch-ppo"), or BCConfig's (trainer "bc")"""
    base: str | None = None
    """a fine-tune's base run: trained first where missing; both stages' time counts"""
    tags: frozenset[str] = frozenset()
    trained_on: str | None = None
    """the protocol condition whose draws it trains on (its learning curve is scored on that
    condition's tuning episodes); None: the env's own episode"""

    def __post_init__(self) -> None:
        unknown = sorted(set(self.tags) - set(TAGS))
        if unknown:
            raise UserError(f"run {self.name!r}: unknown tags {unknown}; the tags are {sorted(TAGS)}")
        if self.trainer not in TRAINERS:
            raise UserError(f"run {self.name!r}: trainer must be one of {TRAINERS}, got {self.trainer!r}")
        if (self.trainer == "dagger") != ("distilled" in self.tags):
            raise UserError(f"run {self.name!r}: the 'dagger' trainer and the 'distilled' tag go together")
        if (self.trainer == "bc") != ("offline" in self.tags):
            raise UserError(f"run {self.name!r}: the 'bc' trainer and the 'offline' tag go together")
        if self.trained_on is not None and self.trained_on not in CONDITIONS:
            raise UserError(f"run {self.name!r}: trained_on must be one of the protocol's conditions "
                             f"{sorted(CONDITIONS)} or None, got {self.trained_on!r}")
        if ("learning-curve" in self.tags) != (self.trained_on is not None):
            raise UserError(f"run {self.name!r}: the 'learning-curve' tag and a trained_on condition go together")
        if (self.base is not None) != ("fine-tune" in self.tags):
            raise UserError(f"run {self.name!r}: a base run and the 'fine-tune' tag go together")


RESIDUAL = {"residual_scale": (2.5, 2.5, 0.05), "residual_deadzone": 0.5}
"""the engineered single-file agent acts through the residual set-point around the target"""
ENGINEERED_WEIGHTS = {"time": 20.0, "collision": 100.0, "success": 50.0}
"""its training reward, as ppo_residual.yml's: colliding costs more than stalling a whole episode"""
FAST_WEIGHTS = {**ENGINEERED_WEIGHTS, "time": 50.0}
"""the time weighted 2.5x"""


CURVE_DRAWS = {
    "c11-starts": (" (starts from the start region)", "perturbed-starts"),
    "random-targets": ("", "random-targets"),
    "random-shifts": (" (physics and wall drawn per episode)", "domain-randomized"),
}
"""the conditions a learning-curve run trains on: what its description adds, its tag"""


def _learning_curve_runs(algo: str, label: str, budget: str) -> list[RunSpec]:
    """One learning-curve run of ``algo`` per condition of CURVE_DRAWS (its YAML block "pd-CONDITION")."""
    return [RunSpec(f"{algo}-{condition}", "sb3", f"{label}, {algo}.yml's recipe on {condition}' draws{note}, {budget}: "
                    "its learning curve", sb3_algorithm=algo, recipe=algo, variant=condition,
                    tags=frozenset({"standard", "pilot", tag, "learning-curve"}), trained_on=condition)
            for condition, (note, tag) in CURVE_DRAWS.items()]


class Tuned(NamedTuple):
    """Where a tuned recipe comes from and where it is written."""

    search: str
    """the search (a registered run; its record: results/search/NAME) whose best trial the recipe is"""
    variant: str
    """its YAML block in the search's algorithm's file: "MODE-VARIANT", and "MODE-VARIANT-CONDITION"
    for each condition of CURVE_DRAWS"""


TUNED_FROM = {"ppo": Tuned("ppo-c11-starts", "tuned"), "ppo-gsde": Tuned("ppo-gsde-c11-starts", "gsde-tuned"),
              "sac": Tuned("sac-c11-starts", "tuned")}
"""tuned recipe (the first part of its runs' names) -> where it comes from. A search on other draws
(ppo-random-targets) is published beside them without being adopted."""


def _tuned_runs(recipe: str, algo: str, label: str, budget: str, tags: frozenset[str] = frozenset()) -> list[RunSpec]:
    """The searched ``recipe`` of TUNED_FROM (its YAML block "pd-VARIANT-CONDITION": the best trial of
    ``scara-agents search``, results/search/) trained on each condition of CURVE_DRAWS: the standard
    algorithm's rows, whose first seeds' checkpoints are also its learning curve."""
    variant = TUNED_FROM[recipe].variant
    return [RunSpec(f"{recipe}-tuned-{condition}", "sb3", f"{label}, the searched recipe on {condition}' draws{note}, "
                    f"{budget}", sb3_algorithm=algo, recipe=algo, variant=f"{variant}-{condition}",
                    tags=frozenset({"standard", "tuned", tag, "learning-curve"}) | tags, trained_on=condition)
            for condition, (note, tag) in CURVE_DRAWS.items()]


INTERFACES = {
    "absolute": ("the env's own set-point action (pd mode)", {}),
    "relative": ("a set-point relative to the target, target + (2.5 rad, 2.5 rad, 0.05 m) x r, no dead zone",
                 {"residual_scale": (2.5, 2.5, 0.05), "residual_deadzone": 0.0}),
    "residual-pd": ("the PD law's voltages towards the target + 0.5 x r (residual policy learning; train with "
                    "--control-mode voltage)", {"residual_scale": (0.5, 0.5, 0.5), "residual_on": "pd"}),
}
"""the interface ablation (issue 58 item 6): interface -> (what the agent's action is, its Config fields)"""


def _interface_ablation() -> list[RunSpec]:
    """The single-file PPO on the c11-starts draws with the env's own reward, 1M steps, once per
    interface of INTERFACES: all else equal."""
    return [RunSpec(f"torch-ppo-interface-{name}", "torch-ppo", f"interface ablation: {note}; the single-file PPO "
                    "with its defaults on starts drawn from the start region, the env's reward, 1M steps",
                    fields={"randomize_start": True, **fields},
                    tags=frozenset({"interface-ablation", "perturbed-starts"} | ({"residual"} if fields else set())))
            for name, (note, fields) in INTERFACES.items()]


def _runs(*specs: RunSpec) -> dict[str, RunSpec]:
    return {spec.name: spec for spec in specs}


RUNS = _runs(
    RunSpec("ppo", "sb3", "SB3 PPO, ppo.yml", sb3_algorithm="ppo", recipe="ppo", tags=frozenset({"standard"})),
    RunSpec("sac", "sb3", "SB3 SAC, sac.yml", sb3_algorithm="sac", recipe="sac", tags=frozenset({"standard"})),
    RunSpec("td3", "sb3", "SB3 TD3, td3.yml", sb3_algorithm="td3", recipe="td3", tags=frozenset({"standard"})),
    *_learning_curve_runs("ppo", "SB3 PPO", "1e7 steps, a checkpoint every 250k"),
    *_learning_curve_runs("sac", "SAC (sbx-rl's)", "1e6 steps, a checkpoint every 62.5k"),
    *_learning_curve_runs("td3", "TD3 (sbx-rl's)", "1e6 steps, a checkpoint every 62.5k"),
    *_learning_curve_runs("tqc", "TQC (sbx-rl's)", "1e6 steps, a checkpoint every 62.5k"),
    *_tuned_runs("ppo", "ppo", "SB3 PPO", "1e7 steps, a checkpoint every 250k"),
    *_tuned_runs("ppo-gsde", "ppo", "SB3 PPO with gSDE", "1e7 steps, a checkpoint every 250k", frozenset({"gsde"})),
    *_tuned_runs("sac", "sac", "SAC (sbx-rl's)", "1e6 steps, a checkpoint every 62.5k"),
    RunSpec("ppo-gsde-c11-starts", "sb3", "SB3 PPO with gSDE, ppo.yml's recipe with use_sde on, on c11-starts' "
            "draws (starts from the start region), 1e7 steps, a checkpoint every 250k: the recipe its search "
            "starts from", sb3_algorithm="ppo", recipe="ppo", variant="gsde-c11-starts",
            tags=frozenset({"standard", "pilot", "gsde", "perturbed-starts", "learning-curve"}),
            trained_on="c11-starts"),
    RunSpec("ppo-residual", "sb3", "SB3 PPO through the residual set-point, ppo_residual.yml's reward",
            sb3_algorithm="ppo", recipe="ppo-residual", tags=frozenset({"engineered", "residual"})),
    RunSpec("ppo-residual-dr", "sb3", "ppo-residual with physics and wall drawn per episode (block pd-dr)",
            sb3_algorithm="ppo", recipe="ppo-residual", variant="dr",
            tags=frozenset({"pilot", "engineered", "residual", "domain-randomized"})),
    RunSpec("ppo-residual-frugal", "sb3", "ppo-residual with an energy cost in the reward (block pd-frugal)",
            sb3_algorithm="ppo", recipe="ppo-residual", variant="frugal",
            tags=frozenset({"pilot", "engineered", "residual", "energy-aware"})),
    RunSpec("torch-ppo", "torch-ppo", "the single-file PPO with its defaults (1M steps, the env's reward)",
            tags=frozenset({"standard"})),
    RunSpec("torch-ppo-lagrangian", "torch-ppo", "the single-file PPO with its defaults, constrained: "
            "PPO-Lagrangian on the collision cost, at most 0 per episode",
            fields={"cost_limit": 0.0}, tags=frozenset({"standard", "constrained"})),
    *_interface_ablation(),
    RunSpec("torch-ppo-dr", "torch-ppo", "the single-file PPO with physics and wall drawn per episode, 3M steps",
            fields={"randomize_params": "all", "total_timesteps": 3_000_000},
            tags=frozenset({"standard", "domain-randomized"})),
    RunSpec("torch-ppo-residual-random", "torch-ppo", "engineered, targets drawn per episode, 3M steps",
            fields={**RESIDUAL, "randomize_target": True, "reward_weights": ENGINEERED_WEIGHTS,
                    "total_timesteps": 3_000_000},
            tags=frozenset({"pilot", "engineered", "residual", "random-targets"})),
    RunSpec("torch-ppo-residual-dr", "torch-ppo", "engineered, physics and wall drawn per episode",
            fields={**RESIDUAL, "randomize_params": "all", "reward_weights": ENGINEERED_WEIGHTS},
            tags=frozenset({"engineered", "residual", "domain-randomized"})),
    RunSpec("torch-ppo-residual-frugal", "torch-ppo", "engineered, energy weighted 0.05 per J",
            fields={**RESIDUAL, "reward_weights": {**ENGINEERED_WEIGHTS, "energy": 0.05}},
            tags=frozenset({"pilot", "engineered", "residual", "energy-aware"})),
    RunSpec("torch-ppo-residual-fast", "torch-ppo", "engineered, the time weighted 2.5x, 3M steps",
            fields={**RESIDUAL, "reward_weights": FAST_WEIGHTS, "total_timesteps": 3_000_000},
            tags=frozenset({"engineered", "residual"})),
    RunSpec("torch-ppo-residual-fast-frugal", "torch-ppo", "-fast with energy weighted 0.03 per J, 3M steps",
            fields={**RESIDUAL, "reward_weights": {**FAST_WEIGHTS, "energy": 0.03}, "total_timesteps": 3_000_000},
            tags=frozenset({"pilot", "engineered", "residual", "energy-aware"})),
    RunSpec("torch-ppo-residual-random-safe", "torch-ppo", "engineered, targets drawn per episode, collisions "
            "priced 3x, 4M steps",
            fields={**RESIDUAL, "randomize_target": True, "reward_weights": {**ENGINEERED_WEIGHTS, "collision": 300.0},
                    "total_timesteps": 4_000_000},
            tags=frozenset({"pilot", "engineered", "residual", "random-targets"})),
    RunSpec("torch-ppo-residual-random-safe-fast", "torch-ppo", "-random-safe fine-tuned with the time "
            "weighted 1.5x, 2M steps",
            fields={**RESIDUAL, "randomize_target": True,
                    "reward_weights": {**ENGINEERED_WEIGHTS, "time": 30.0, "collision": 300.0},
                    "total_timesteps": 2_000_000},
            base="torch-ppo-residual-random-safe",
            tags=frozenset({"pilot", "engineered", "residual", "random-targets", "fine-tune"})),
    RunSpec("torch-ppo-residual-fast-rsi", "torch-ppo", "-fast with 80 % of the training episodes started on "
            "the 8 mm optimal reference's path, entropy 0.01, 4M steps",
            fields={**RESIDUAL, "reward_weights": FAST_WEIGHTS, "demo_resets": 0.8, "demo_wall_margin": 0.008,
                    "ent_coef": 0.01, "total_timesteps": 4_000_000},
            tags=frozenset({"pilot", "engineered", "residual", "demonstrations"})),
    RunSpec("torch-ppo-residual-random-replay", "torch-ppo", "-random fine-tuned for 1M steps with 30 % of the "
            "episodes on targets it recently failed",
            fields={**RESIDUAL, "randomize_target": True, "reward_weights": ENGINEERED_WEIGHTS,
                    "target_replay": 0.3, "total_timesteps": 1_000_000},
            base="torch-ppo-residual-random",
            tags=frozenset({"engineered", "residual", "random-targets", "fine-tune", "also-shielded"})),
    RunSpec("torch-ppo-residual-fast-starts", "torch-ppo", "-fast fine-tuned for 1M steps on the protocol's "
            "training distribution: starts drawn from the start region, noisy sensors at the protocol's levels",
            fields={**RESIDUAL, "reward_weights": FAST_WEIGHTS, "randomize_start": True, "sensor_noise": 1.0,
                    "total_timesteps": 1_000_000},
            base="torch-ppo-residual-fast",
            tags=frozenset({"engineered", "residual", "fine-tune", "perturbed-starts", "sensor-noise"})),
    RunSpec("torch-ppo-residual-random-starts", "torch-ppo", "-random-replay fine-tuned for 1M steps on targets "
            "and starts drawn per episode with noisy sensors at the protocol's levels",
            fields={**RESIDUAL, "randomize_target": True, "reward_weights": ENGINEERED_WEIGHTS, "target_replay": 0.3,
                    "randomize_start": True, "sensor_noise": 1.0, "total_timesteps": 1_000_000},
            base="torch-ppo-residual-random-replay",
            tags=frozenset({"engineered", "residual", "random-targets", "fine-tune", "perturbed-starts",
                            "sensor-noise"})),
    RunSpec("torch-ppo-residual-fast-shield", "torch-ppo", "-fast-frugal's reward behind the shield, in "
            "training and evaluation, 1M steps",
            fields={**RESIDUAL, "reward_weights": {**FAST_WEIGHTS, "energy": 0.03}, "shield": True,
                    "total_timesteps": 1_000_000},
            tags=frozenset({"pilot", "engineered", "residual", "energy-aware", "shielded"})),
    RunSpec("dagger-mpc-rti", "dagger", "DAgger on the real-time MPC (pd mode) over the c11-starts, random-targets "
            "and random-shifts training draws, in the residual set-point's space around the target",
            fields={}, tags=frozenset({"distilled", "residual", "perturbed-starts", "random-targets",
                                       "domain-randomized"})),
    RunSpec("dagger-mpc-rti-voltage", "dagger", "DAgger on the real-time MPC in voltage mode, as a correction of "
            "the PD law's voltages (PD + 2 r; train with --control-mode voltage), over the same draws",
            fields={"residual_on": "pd", "residual_scale": (2.0, 2.0, 2.0), "residual_deadzone": 0.0},
            tags=frozenset({"distilled", "residual", "perturbed-starts", "random-targets", "domain-randomized"})),
    RunSpec("bc-c11-expert", "bc", "behaviour cloning of scara/c11/expert-v0 (agents.experiments.datasets) in the "
            "residual set-point's space", fields={"dataset": "scara/c11/expert-v0", **RESIDUAL},
            tags=frozenset({"offline", "residual", "perturbed-starts"})),
    RunSpec("bc-c11-mixed", "bc", "behaviour cloning of scara/c11/mixed-v0 (the expert's and random episodes) in "
            "the residual set-point's space", fields={"dataset": "scara/c11/mixed-v0", **RESIDUAL},
            tags=frozenset({"offline", "residual", "perturbed-starts"})),
    RunSpec("bc-c11-expert-plain", "bc", "behaviour cloning of scara/c11/expert-v0 in the env's own actions",
            fields={"dataset": "scara/c11/expert-v0"}, tags=frozenset({"pilot", "offline", "perturbed-starts"})),
)
"""every registered run, in the campaign's order"""


def spec(name: str) -> RunSpec:
    """The registered run ``name``; an unknown name is an error that lists the registered ones."""
    if name not in RUNS:
        raise UserError(f"no registered run {name!r}; the registered runs are {sorted(RUNS)}")
    return RUNS[name]


def tagged(tag: str) -> tuple[str, ...]:
    """The names of the registered runs that carry ``tag``."""
    if tag not in TAGS:
        raise UserError(f"unknown tag {tag!r}; the tags are {sorted(TAGS)}")
    return tuple(name for name, s in RUNS.items() if tag in s.tags)
