"""The evaluation protocol: named conditions, each a documented distribution with its own seeds.

A `Condition` is what a number in a results table is a claim about: the environment
(its id's physics, the task, the sim-to-real options), what is drawn per episode (the start,
the target, the robot's parameters, the sensor noise) and the evaluation seeds it is drawn
from. `evaluate` runs any policy on any condition; it is the one way the comparison,
the datasets and a user's own agent are scored.

| condition | what is drawn per episode (seed band: ``Condition.seed`` + episode) |
|---|---|
| ``c11`` | nothing: the seed paper's episode, start (0, 0, 0), target (2, 2, 0.3); one episode |
| ``c11-starts`` | the start: q1, q2 in (0 +- 0.05) rad, q3 in [0, 0.05] m (``START_OFFSETS``) |
| ``random-targets`` | the target, as ``randomize_target=True`` (the env card's region) |
| ``random-shifts`` | the parameters, as ``randomize_params="all"`` (the card's ranges) |
| ``corners`` | the parameters at a corner of the "all" ranges: each parameter at one end of its range, the end drawn per parameter (``corner_params``) |
| ``load-x2`` | the start (as c11-starts), with the load mass x2 (0.5 -> 1.0 kg) |
| ``wall-closer`` | the start, with the wall 2 cm closer (x_obs 0.35 -> 0.37 m) |
| ``current-limits-15`` | the start, with every current limit -15 % |
| ``resistance+20`` | the start, with every motor resistance +20 % |
| ``sensor-noise`` | sensor noise ``SENSOR_NOISE`` (q 1e-3, rates 0.01, currents 0.02 A) each step |
| ``sensor-noise-x5`` | five times that |
| ``delay-1`` | the start, with one control step of actuation delay (``action_delay=1``) |
| ``rate-limit-20`` | the start, with the action slew-limited to 20 units/s (``action_rate_limit=20``) |

Everything else is the C11 task of the protocol's one id, ``ENV_ID`` (the latest id, unless
given). Seeds: every
condition draws from its own band of 10^7 seeds from 10^9 on (``Condition.seed``); the
tuning set (`tuning`) from 10^8 on; training, by the agents' convention, below 10^8
(``TRAINING_SEED_LIMIT``): no seed that tunes or trains anything is an evaluation seed.
`noise_condition` and `shift_condition` give the points of the robustness curves
(sensor noise, a parameter shift, at any magnitude) on the same seeds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from scara_gym.benchmark.episodes import run_episodes
from scara_gym.envs.randomization import ParameterRanges, leaf_value
from scara_gym.envs.task import START_REGION, draw_start
from scara_gym.model import checks
from scara_gym.model.checks import UserError, UserTypeError
from scara_gym.model.params import DEFAULT_PARAMS
from scara_gym.registration import LATEST_ENV_ID

ENV_ID = LATEST_ENV_ID
"""the id every condition runs on: evaluation, comparison, curves, sweeps, tuning, the datasets and the
evaluation cache read it (a result names it)"""
TRAINING_SEED_LIMIT = 10**8
"""training (run seeds and every reset seed a trainer uses) stays below this"""
TUNING_SEED = 10**8
"""the first seed of the tuning set (its band: 10^8 .. 10^9 - 1)"""
EVALUATION_SEED = 10**9
"""the first evaluation seed; condition k's band starts at 10^9 + k 10^7"""
SEED_BAND = 10**7
START_OFFSETS = START_REGION
"""the start region: offsets [rad, rad, m] from the C11 start (0, 0, 0), drawn uniformly (the
environments' ``randomize_start=True`` region, for training on it)"""
SENSOR_NOISE = {"q": 1e-3, "rate": 0.01, "current": 0.02}
"""the sensor noise of "sensor-noise" (standard deviations: rad and m, rad/s and m/s, A)"""
_START_STREAM = 0x5CA4A  # the start's generator: (seed, this), apart from the env's own draws
_CORNER_STREAM = 0xC0C0  # a corner's generator: (seed, this)

_axes = DEFAULT_PARAMS.axes


@dataclass(frozen=True)
class Condition:
    """One evaluation condition (module table): environment arguments, fixed parameter
    overrides, whether the start is drawn, the first seed and the default episode count.
    """

    name: str
    description: str
    seed: int
    env_kwargs: Mapping = field(default_factory=dict)
    """environment arguments: randomize_target, randomize_params, sensor_noise, action_delay, ..."""
    params: Mapping = field(default_factory=dict)
    """dotted parameter path -> value, fixed for every episode"""
    random_starts: bool = False
    """the start drawn from START_OFFSETS around the C11 start, per episode"""
    corners: str | None = None
    """a preset of `scara_gym.envs.randomization` whose parameters sit at a corner of its ranges,
    drawn per episode (``corner_params``; set through the reset options)"""
    episodes: int = 100
    """the default number of episodes (1 where nothing is drawn)"""

    @property
    def deterministic(self) -> bool:
        """Nothing is drawn per episode: a deterministic policy has one episode here."""
        kwargs = self.env_kwargs
        return not (self.random_starts or self.corners or kwargs.get("randomize_target") or kwargs.get("randomize_params")
                    or kwargs.get("sensor_noise") or kwargs.get("observation_noise"))

    def make_env(self, control_mode: str = "pd", env_id: str = ENV_ID, **kwargs) -> gym.Env:
        """The condition's environment; kwargs: further arguments (e.g. a run's goal_tolerance)."""
        clash = sorted(set(kwargs) & (set(self.env_kwargs) | {"params", "control_mode"}))
        if clash:
            raise UserError(f"the condition {self.name!r} sets {clash} itself")
        return gym.make(env_id, control_mode=control_mode, params=DEFAULT_PARAMS.replace(dict(self.params)),
                        **dict(self.env_kwargs), **kwargs)

    def seeds(self, episodes: int | None = None) -> list[int]:
        """The evaluation seeds of the first ``episodes`` episodes (default: ``self.episodes``)."""
        n = self.episodes if episodes is None else checks.integer("episodes", episodes, 1, SEED_BAND)
        return list(range(self.seed, self.seed + n))

    def with_seed(self, seed: int) -> Condition:
        """The same distribution from another first seed (a rerun on other episodes of its kind)."""
        return dataclasses.replace(self, seed=checks.seed("seed", seed))

    def options(self, seed: int) -> dict | None:
        """The reset options of the episode of ``seed``: its drawn start, where the start is drawn,
        and its corner's parameters, where corners are drawn.
        """
        options = {}
        if self.random_starts:
            rng = np.random.default_rng((int(seed), _START_STREAM))
            options["start"] = tuple(draw_start(rng, DEFAULT_PARAMS.task.start, START_OFFSETS).tolist())
        if self.corners:
            options["params"] = corner_params(self.corners, seed)
        return options or None


def corner_params(preset: str, seed: int) -> dict[str, float]:
    """A corner of a preset's ranges (around the C11 parameters): every path at its low or its high
    end, each end drawn with probability 1/2 from ``seed``'s own generator (apart from the start's
    and the environment's), so that the 2^14 corners of "all" are drawn alike.
    """
    rng = np.random.default_rng((int(seed), _CORNER_STREAM))
    ranges = ParameterRanges.preset(preset, DEFAULT_PARAMS).ranges
    return {path: float(bounds[int(end)]) for (path, bounds), end in zip(ranges.items(), rng.integers(0, 2, len(ranges)))}


def _starts_with(name: str, description: str, index: int, **kwargs) -> Condition:
    return Condition(name, description + ", from starts in the start region", EVALUATION_SEED + index * SEED_BAND,
                     random_starts=True, **kwargs)


CONDITIONS: dict[str, Condition] = {c.name: c for c in (
    Condition("c11", "the seed paper's episode: the C11 target (2, 2, 0.3) from (0, 0, 0), the wall",
              EVALUATION_SEED, episodes=1),
    _starts_with("c11-starts", "the C11 target", 1),
    Condition("random-targets", "targets drawn per episode beyond the wall", EVALUATION_SEED + 2 * SEED_BAND,
              env_kwargs={"randomize_target": True}),
    Condition("random-shifts", "the C11 target, parameters drawn per episode from the 'all' ranges "
              "(load, link masses, resistances, torque constants, current limits, wall position and height)",
              EVALUATION_SEED + 3 * SEED_BAND, env_kwargs={"randomize_params": "all"}),
    Condition("corners", "the C11 target, the parameters at a corner of the 'all' ranges drawn per episode: "
              "each of load, link masses, resistances, torque constants, current limits, wall position and "
              "height at one end of its range", EVALUATION_SEED + 12 * SEED_BAND,
              env_kwargs={"randomize_params": "all"}, corners="all"),
    _starts_with("load-x2", "load mass x2 (m3L 0.5 -> 1.0 kg)", 4,
                 params={"arm.load_mass": 2 * DEFAULT_PARAMS.arm.load_mass}),
    _starts_with("wall-closer", "wall 2 cm closer to the arm's start (x_obs 0.35 -> 0.37 m)", 5,
                 params={"obstacle.x_position": DEFAULT_PARAMS.obstacle.x_position + 0.02}),
    _starts_with("current-limits-15", "current limits -15 %", 6,
                 params={f"axes.{i}.current_limit": 0.85 * a.current_limit for i, a in enumerate(_axes)}),
    _starts_with("resistance+20", "motor resistances +20 %", 7,
                 params={f"axes.{i}.resistance": 1.2 * a.resistance for i, a in enumerate(_axes)}),
    Condition("sensor-noise", "the C11 episode with noisy sensors (q 1e-3, rates 0.01, currents 0.02 A)",
              EVALUATION_SEED + 8 * SEED_BAND, env_kwargs={"sensor_noise": SENSOR_NOISE}),
    Condition("sensor-noise-x5", "the C11 episode with noisy sensors at 5x sensor-noise's levels",
              EVALUATION_SEED + 9 * SEED_BAND, env_kwargs={"sensor_noise": {k: 5 * v for k, v in SENSOR_NOISE.items()}}),
    _starts_with("delay-1", "one control step of actuation delay", 10, env_kwargs={"action_delay": 1}),
    _starts_with("rate-limit-20", "the action slew-limited to 20 action units per second", 11,
                 env_kwargs={"action_rate_limit": 20.0}),
)}
"""The protocol's conditions by name (module table)."""
FIXED_SHIFTS = ("load-x2", "wall-closer", "current-limits-15", "resistance+20")
"""the conditions that shift the robot's parameters by a fixed amount"""


def protocol_record(names) -> dict:
    """name -> what a results file records of each condition: its description, arguments, draws
    and first seed (JSON-ready).
    """
    out = {}
    for name in names:
        c = get_condition(name)
        out[c.name] = {"description": c.description, "seed": c.seed, "env_kwargs": dict(c.env_kwargs),
                       "params": dict(c.params), "random_starts": c.random_starts, "corners": c.corners,
                       "start_offsets": [o.tolist() for o in START_OFFSETS] if c.random_starts else None}
    return out


def get_condition(name: str | Condition) -> Condition:
    """The protocol's condition of that name (ValueError listing them otherwise); a Condition as it is."""
    if isinstance(name, Condition):
        return name
    if name not in CONDITIONS:
        raise UserError(f"unknown condition {name!r}; the protocol's conditions are {sorted(CONDITIONS)}")
    return CONDITIONS[name]


def tuning(name: str, episodes: int | None = None) -> Condition:
    """The tuning set of a condition: its distribution on tuning seeds, never scored.

    Args:
        name: the condition's name.
        episodes: the tuning set's size (None: the condition's own count).

    Returns:
        A Condition on the seeds 10^8 + the condition's band, for choosing a policy's parameters.
    """
    base = get_condition(name)
    if episodes is not None:
        checks.integer("episodes", episodes, 1, SEED_BAND)
    index = (base.seed - EVALUATION_SEED) // SEED_BAND
    return dataclasses.replace(base, name=f"{base.name} (tuning)", seed=TUNING_SEED + index * SEED_BAND,
                               episodes=base.episodes if episodes is None else episodes)


def noise_condition(scale: float) -> Condition:
    """"sensor-noise" at ``scale`` times its levels (the noise curve's points), on its seeds."""
    scale = checks.real("scale", scale, 0.0, 1e3)
    base = CONDITIONS["sensor-noise"]
    return dataclasses.replace(base, name=f"sensor noise at {scale:g}x",
                               description=f"the C11 episode with noisy sensors at {scale:g}x sensor-noise's levels",
                               env_kwargs={"sensor_noise": {k: scale * v for k, v in SENSOR_NOISE.items()}})


def shift_condition(path: str, factor: float) -> Condition:
    """The parameter at dotted ``path`` (every axis's for "axes.*.NAME") scaled by ``factor``,
    from starts in the start region, on c11-starts' seeds (a robustness curve's point).
    """
    factor = checks.real("factor", factor, 0.0, 100.0)
    paths = [path.replace("*", str(i)) for i in range(len(_axes))] if "*" in path else [path]
    params = {p: factor * leaf_value(DEFAULT_PARAMS, p) for p in paths}
    base = CONDITIONS["c11-starts"]
    return dataclasses.replace(base, name=f"{path} x{factor:g}",
                               description=f"{path} x{factor:g}, from starts in the start region", params=params)


def draws_nothing(env) -> bool:
    """Whether the environment itself draws nothing per episode (start, target, parameters, noise)."""
    task = env.unwrapped._task
    return not (task.randomize_target or task.randomization or task.start_region is not None
                or task.sim_to_real.noisy)


def evaluate(condition: Condition | str, policy_factory: Callable | None = None, control_mode: str = "pd",
             episodes: int | None = None, env_id: str = ENV_ID, record: int = 1, env_kwargs=None, *,
             policy: Callable | None = None) -> dict:
    """A policy's episodes in a condition of the protocol, on the condition's evaluation seeds.

    A deterministic condition runs a deterministic policy's episode once per distinct outcome
    (run_episodes' shortcut).

    Args:
        condition: a Condition or the name of one (``CONDITIONS``).
        policy_factory: ``policy_factory(env)`` returns the policy, a callable obs -> action (for
            a policy that needs the env, e.g. its task's parameters).
        policy: or the policy itself, a plain callable obs -> action (e.g. a function); give one
            of the two. A ``reset()`` it has is called before each episode.
        control_mode: "pd" or "voltage".
        episodes: how many of the condition's seeds (None: its own count).
        env_id: the registered id the episodes run on.
        record: record a trace of the first ``record`` episodes.
        env_kwargs (dict | None): further environment arguments (over the condition's).

    Returns:
        Per-episode arrays (success, collisions, reach_time, energy, ...; see
        scara_gym.benchmark.episodes) and "condition", the condition's name.
    """
    if (policy_factory is None) == (policy is None):
        raise UserTypeError("evaluate takes one of policy_factory (env -> policy) and policy (obs -> action), "
                            f"got {'both' if policy is not None else 'neither'}")
    condition = get_condition(condition)
    checks.integer("record", record, 0)
    if env_kwargs is not None and not isinstance(env_kwargs, Mapping):
        raise UserTypeError(f"env_kwargs must be a mapping of environment arguments or None, got {env_kwargs!r}")
    env = condition.make_env(control_mode, env_id, **(env_kwargs or {}))
    seeds = condition.seeds(episodes)
    result = run_episodes(env, policy if policy is not None else policy_factory(env), seeds, [condition.options(s) for s in seeds],
                          identical=condition.deterministic and draws_nothing(env), record=record)
    result["condition"] = condition.name
    return result
