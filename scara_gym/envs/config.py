"""EnvConfig: the one configuration of every Scara-C11 environment (gymnax's ``EnvParams``,
HighwayEnv's ``default_config``).

One frozen value holds every argument of the task; its defaults are the latest id's
(Scara-C11-v2). `ScaraTask` takes it, and the single, vector,
CUDA and goal environments take ``config=`` plus keyword overrides of its fields
(``ScaraEnv(control_mode="voltage")`` is ``ScaraEnv(config=EnvConfig(control_mode="voltage"))``).
Each registered id is such a value (``scara_gym.registration``), and the cards' argument
lists are written from the fields' documentation here (`arguments_markdown`). The values
are checked where a task is built from them, each mistake naming its field and what it allows.
"""

from __future__ import annotations

import dataclasses
import inspect
from dataclasses import dataclass, field
from typing import Any


def _doc(text: str) -> dict:
    return {"doc": inspect.cleandoc(text)}


@dataclass(frozen=True)
class EnvConfig:
    """Every argument of a Scara-C11 task, with the latest id's defaults."""

    control_mode: str = field(default="pd", metadata=_doc('"pd" or "voltage", see the action space.'))
    obstacle: bool = field(default=True, metadata=_doc("the wall of task c and the widened voltage near it."))
    collision: str = field(default="terminate", metadata=_doc('"terminate" or "penalty".'))
    target: Any = field(default=None, metadata=_doc("q^ [rad, rad, m]; None: the C11 target (2, 2, 0.3)."))
    start: Any = field(default=None, metadata=_doc("q(0) [rad, rad, m]; None: the C11 start (0, 0, 0)."))
    randomize_target: bool = field(default=False, metadata=_doc("draw q^ per episode, see the starting state."))
    reward_weights: Any = field(default=None, metadata=_doc("a RewardWeights or a dict of its fields."))
    control_dt: float = field(default=0.01, metadata=_doc("control step [s]; render_fps = 1 / control_dt."))
    time_limit: float = field(default=3.0, metadata=_doc("""
        horizon of the time_left feature [s]; keep max_episode_steps = time_limit / control_dt
        when changing either."""))
    params: Any = field(default=None, metadata=_doc("""
        a ScaraParams, or a dict of dotted-path overrides of the C11 defaults, e.g.
        {"arm.load_mass": 1.0, "obstacle.height": 0.2}."""))
    rtol: float = field(default=1e-7, metadata=_doc("""
        relative integration tolerance inside the step (scipy's meaning), in [1e-14, 1e-2];
        the default is the latest id's (Scara-C11-v2); Scara-C11-v0 registers 1e-5,
        Scara-C11-v1 1e-6."""))
    atol: float = field(default=1e-9, metadata=_doc("""
        absolute integration tolerance inside the step, in [1e-16, 1e-2]; Scara-C11-v0
        registers 1e-6, Scara-C11-v1 1e-8. How close a tolerance stays to a tight-tolerance
        run is measured by ``scara-c11 accuracy``."""))
    exact_switches: bool = field(default=True, metadata=_doc("""
        locate every mode switch inside the integration steps (a current limit or the PD
        law's saturation reached and left within one step is found; the saturation is a
        located switch, not a kink). False is the first releases' integration
        (Scara-C11-v0), which sees switches at the ends of integration steps only."""))
    randomize_params: Any = field(default=False, metadata=_doc("""
        False, True ("physics"), "physics", "wall", "all" or a dict {dotted path: (low,
        high)}: parameters drawn per episode, see the starting state; the observation bounds
        then hold the ranges' ends."""))
    observation_noise: Any = field(default=None, metadata=_doc("""
        sim-to-real: {field: standard deviation} in the field's unit, e.g. {"q": 1e-3,
        "rate": 0.05, "current": 0.02}; fields of the observation ("q", "rate", "current",
        "target_error", "tip_x", ...: a vector field's std applies to each entry) or entries
        by the table's names ("q3"). Zero-mean Gaussian noise per step from the episode's
        generator, added to the returned observation only (the physics, reward and episode
        end see the true state). Each entry gets its own noise: noise on q does not reach
        target_error or the tip; for that, use sensor_noise."""))
    action_delay: int = field(default=0, metadata=_doc("""
        sim-to-real: dead time in control steps, in [0, 100]: the action given at step t is
        applied at step t + k; the first k steps apply the neutral action (the start as
        set-point in "pd" mode, 0 V in "voltage" mode)."""))
    action_rate_limit: Any = field(default=None, metadata=_doc("""
        sim-to-real: the applied action moves towards the (delayed) given one by at most
        this many action units per second (the action spans [-1, 1]; e.g. 20 allows 0.2 per
        0.01 s step), starting from the neutral action."""))
    sensor_noise: Any = field(default=None, metadata=_doc("""
        sim-to-real: noisy sensors, {channel: standard deviation} over "q", "rate" and
        "current" (or entries "q1" ... "current3"), e.g. {"q": 1e-3, "rate": 0.01, "current":
        0.02}: the noise is added to the measured q, rates and currents and target_error,
        tip_x, tip_y, wall_distance and height_margin are computed from the noisy
        measurements (as a controller computes them from its sensors); drawn before any
        observation_noise, from the episode's generator. Not on the CUDA vector env."""))
    randomize_start: Any = field(default=False, metadata=_doc("""
        True draws the start per episode as ``start`` + uniform offsets in q1, q2 in [-0.05,
        0.05] rad, q3 in [0, 0.05] m (the evaluation protocol's start region), after the
        parameters and before the target; (low, high) gives offsets of its own [rad, rad,
        m]. ``reset(options={"start": ...})`` overrides it."""))
    tolerance_weights: Any = field(default=None, metadata=_doc("""
        a dict from state groups ("q", "rate", "current", "energy") to a factor in [1e-3,
        1e3] on rtol and atol for that group's components (the others 1), e.g. {"q": 0.03,
        "current": 30}; no id registers it (at v2's tolerances those weights miss the current
        target on a held-out episode)."""))

    def replace(self, **overrides) -> EnvConfig:
        """This configuration with some fields changed; an unknown name is an error that
        lists the fields.
        """
        unknown = sorted(set(overrides) - set(FIELDS))
        if unknown:
            raise TypeError(f"unknown environment argument(s) {unknown}; the arguments are {list(FIELDS)}")
        return dataclasses.replace(self, **overrides) if overrides else self

    def as_dict(self) -> dict:
        """The fields as keyword arguments (shallow: the values as given)."""
        return {name: getattr(self, name) for name in FIELDS}


FIELDS = tuple(f.name for f in dataclasses.fields(EnvConfig))
"""the names of EnvConfig's fields, in order"""


def make_config(config: EnvConfig | None, overrides: dict, base: EnvConfig | None = None) -> EnvConfig:
    """``config`` (or ``base``, default ``EnvConfig()``) with ``overrides``: what each
    environment class's ``config=`` and keyword arguments give.
    """
    if config is not None and not isinstance(config, EnvConfig):
        raise TypeError(f"config must be an EnvConfig (or None), got {config!r}")
    start = config if config is not None else (base if base is not None else EnvConfig())
    return start.replace(**overrides)


def arguments_markdown(defaults: EnvConfig, extra: tuple[tuple[str, Any, str], ...] = (),
                       indent: str = "") -> str:
    """The card's argument list: ``- name (default): doc`` per field of EnvConfig (the
    defaults of ``defaults``), then ``extra`` (name, default, doc) entries.
    """
    lines = []
    entries = [(f.name, getattr(defaults, f.name), f.metadata["doc"]) for f in dataclasses.fields(EnvConfig)]
    for name, default, doc in (*entries, *extra):
        text = f"- {name} ({repr(default).replace(chr(39), chr(34))}): {' '.join(doc.split())}"
        lines.extend(_wrapped(text, indent))
    return "\n".join(lines)


def _wrapped(text: str, indent: str, width: int = 92) -> list[str]:
    """``text`` as lines of at most ``width`` characters, the continuation lines indented two more."""
    words, lines, line = text.split(" "), [], ""
    for word in words:
        candidate = f"{line} {word}" if line else word
        if len(candidate) > width and line:
            lines.append(line)
            line = "  " + word
        else:
            line = candidate
    lines.append(line)
    return [indent + text_line for text_line in lines]
