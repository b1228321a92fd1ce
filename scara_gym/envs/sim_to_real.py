"""Sim-to-real options: sensor noise, observation noise, actuation delay and an action rate limit.

All four are off by default and apply to any environment id (single and CPU vector):

- ``sensor_noise``: ``{channel: standard deviation}`` over the measured channels ``"q"``
  [rad, rad, m], ``"rate"`` [rad/s, rad/s, m/s] and ``"current"`` [A] (a channel's std applies
  to its three axes) or single ones by the card's names (``"q1"``, ``"current3"``). The noise
  is drawn per step and added to the measurements, and every entry derived from them is
  computed from the noisy measurements, as a controller on a real robot computes them:
  ``target_error`` = q^ - q_measured, ``tip_x``, ``tip_y`` by the forward kinematics of the
  measured angles, ``wall_distance`` from the measured tip and ``height_margin`` from the
  measured q3. ``critical`` (the drive's own mode) and ``time_left`` are not measurements.

- ``observation_noise``: ``{field: standard deviation}`` in the field's unit, over the
  fields of the observation (``"q"``, ``"rate"``, ``"current"``, ``"target_error"``,
  ``"tip_x"``, ... of ``OBSERVATION_LAYOUT``; a vector field's std applies to each of its
  entries) or single entries by the card's names (``"q3"``, ``"current1"``). Zero-mean
  Gaussian noise, drawn per step from the episode's random generator, is added to the
  returned observation, which is then clipped to the observation space. The physics, the
  reward and the episode end see the true state.
- ``action_delay``: k >= 0 control steps of dead time. The action given at step t is
  applied at step t + k; the first k steps of an episode apply the neutral action (the
  set-point at the start in "pd" mode: the robot holds still; zero volts in "voltage" mode).
- ``action_rate_limit``: r > 0 in action units per second (the action spans [-1, 1]): the
  applied action moves towards the (delayed) action by at most r * control_dt per step,
  starting from the neutral action. A slew-rate limit of the actuator.

Sensor noise is drawn first, then observation noise (both may be given). Actions beyond [-1, 1] are clipped (and counted in ``clipped_actions``) before the delay
and the rate limit. With a delay or a rate limit the action applied in a step is in
``info["applied_action"]``.

No gymnasium import here: the task object (`scara_gym.envs.task`) uses it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field as dataclass_field

import numpy as np

from scara_gym.envs.core import O_HEIGHT, O_TARGET_ERROR, O_TIP_X, O_TIP_Y, O_WALL
from scara_gym.model import checks
from scara_gym.model.dynamics import tip_position

MAX_ACTION_DELAY = 100   # [control steps]
NOISE_STD_MAX = 1e3      # [the field's unit]; beyond, every noisy value sits on a bound
SENSOR_CHANNELS = ("q", "rate", "current")
"""the measured channels of ``sensor_noise``, in the observation's first nine entries"""
N_SENSED = 9


@dataclass(frozen=True)
class SimToReal:
    """The checked sim-to-real options of one environment (see the module)."""

    noise_std: np.ndarray
    """per observation entry, the noise's standard deviation in the entry's unit (float64)"""
    action_delay: int = 0
    """control steps between giving an action and applying it"""
    action_rate_limit: float | None = None
    """largest change of the applied action per second [action units / s]; None: none"""
    control_dt: float = 0.01
    """the control step [s] (the rate limit's time scale)"""
    sensor_std: np.ndarray = None
    """per measured channel (q1..q3, rates, currents), the sensor noise's standard deviation"""
    observation_noisy: bool = dataclass_field(init=False, repr=False, compare=False)
    """per-entry observation noise on some entry"""
    sensor_noisy: bool = dataclass_field(init=False, repr=False, compare=False)
    """noise on some sensor channel"""
    noisy: bool = dataclass_field(init=False, repr=False, compare=False)
    """either (the three are decided once, in __post_init__)"""

    def __post_init__(self) -> None:
        # read at every step: decided once (np.any costs microseconds a call)
        object.__setattr__(self, "observation_noisy", bool(np.any(self.noise_std > 0.0)))
        object.__setattr__(self, "sensor_noisy", self.sensor_std is not None and bool(np.any(self.sensor_std > 0.0)))
        object.__setattr__(self, "noisy", self.observation_noisy or self.sensor_noisy)

    @classmethod
    def from_arguments(cls, observation_noise, action_delay, action_rate_limit, control_dt: float,
                       layout: Mapping, names: tuple[str, ...], sensor_noise=None) -> SimToReal:
        """Check the four environment arguments; layout: field -> slice or index of the flat
        observation; names: one name per entry.
        """
        std = _stds("observation_noise", observation_noise, layout, names)
        sensed = {field: layout[field] for field in SENSOR_CHANNELS}
        sensor = _stds("sensor_noise", sensor_noise, sensed, names[:N_SENSED])
        delay = checks.integer("action_delay", action_delay, 0, MAX_ACTION_DELAY)
        if action_rate_limit is not None:
            action_rate_limit = checks.real("action_rate_limit", action_rate_limit, 1e-6, 1e9,
                                            unit="action units per second")
        return cls(std, delay, action_rate_limit, control_dt, sensor)

    @property
    def shapes_actions(self) -> bool:
        """True where the applied action can differ from the given one (clipping aside)."""
        return self.action_delay > 0 or self.action_rate_limit is not None


def _stds(argument: str, value, layout: Mapping, names: tuple[str, ...]) -> np.ndarray:
    """One standard deviation per entry of ``names`` from a {field or entry name: std} argument."""
    std = np.zeros(len(names))
    if value is None:
        return std
    allowed = sorted(set(layout) | set(names), key=lambda n: (n not in layout, n))
    for field, v in checks.mapping(argument, value, allowed).items():
        v = checks.real(f"{argument}[{field!r}]", v, 0.0, NOISE_STD_MAX, unit="the field's unit")
        std[layout[field] if field in layout else names.index(field)] = v
    return std


class Actuator:
    """The delay line and the slew-limited output of N robots (numpy, vectorized over robots)."""

    def __init__(self, options: SimToReal, num_robots: int) -> None:
        self.options = options
        self.pending = np.zeros((num_robots, options.action_delay, 3))
        """actions given and not yet applied, oldest first"""
        self.applied = np.zeros((num_robots, 3))
        """the action applied in each robot's last step"""
        rate = options.action_rate_limit
        self.max_change = None if rate is None else rate * options.control_dt

    def reset(self, i: int, neutral: np.ndarray) -> None:
        """Robot i's new episode: the line full of the neutral action, the output at it."""
        self.pending[i] = neutral
        self.applied[i] = neutral

    def apply(self, rows: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """The actions the robots ``rows`` (indices) apply this step, given ``actions``
        (clipped to [-1, 1]) of shape (len(rows), 3); advances their delay lines.
        """
        out = actions
        if self.options.action_delay:
            out = self.pending[rows, 0].copy()
            self.pending[rows, :-1] = self.pending[rows, 1:]
            self.pending[rows, -1] = actions
        if self.max_change is not None:
            previous = self.applied[rows]
            out = previous + np.clip(out - previous, -self.max_change, self.max_change)
        self.applied[rows] = out
        return out


def sense(obs: np.ndarray, std: np.ndarray, rng: np.random.Generator, p, obstacle: bool, low: np.ndarray,
          high: np.ndarray) -> np.ndarray:
    """One observation (float32) as noisy sensors give it: Gaussian noise of ``std`` on the nine
    measured entries (drawn only where std > 0, from ``rng``) and the derived entries computed
    from the noisy measurements with the robot's geometry and wall (``p``: its PARAMS record),
    clipped to [low, high] (float64 out).
    """
    out = obs.astype(np.float64)
    noisy = std > 0.0
    noise = np.zeros(N_SENSED)
    noise[noisy] = rng.standard_normal(int(noisy.sum())) * std[noisy]
    out[:N_SENSED] += noise
    out[O_TARGET_ERROR:O_TARGET_ERROR + 3] -= noise[:3]
    q1, q2, q3 = out[0], out[1], out[2]
    tip_x, tip_y, _ = tip_position(q1, q2, q3, p)
    out[O_TIP_X], out[O_TIP_Y] = tip_x, tip_y
    if obstacle:
        out[O_WALL], out[O_HEIGHT] = tip_x - p["wall_x"], q3 - p["wall_height"]
    return np.clip(out, low, high)


def add_noise(obs: np.ndarray, std: np.ndarray, rng: np.random.Generator, low: np.ndarray,
              high: np.ndarray) -> np.ndarray:
    """One observation (float32) plus zero-mean Gaussian noise of ``std`` per entry, clipped
    to [low, high]; draws only for the entries with std > 0, from ``rng``.
    """
    noisy = std > 0.0
    out = obs.astype(np.float64)
    out[noisy] += rng.standard_normal(int(noisy.sum())) * std[noisy]
    return np.clip(out, low, high).astype(np.float32)
