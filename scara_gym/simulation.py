"""Python side of the compiled integrator: configuration, trajectories and events.

:class:`Simulator` owns the arrays one simulation needs and advances a state in
chunks (the environment calls it once per control step); :func:`simulate` runs
one segment and returns a :class:`Trajectory`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from scara_gym import layout as L
from scara_gym.integrator import initial_modes, integrate
from scara_gym.params import DEFAULT_PARAMS, ScaraParams

FORMS = {"explicit": L.FORM_EXPLICIT, "implicit": L.FORM_IMPLICIT}
CONTROLS = {"pd": L.CONTROL_PD, "voltage": L.CONTROL_VOLTAGE}
CRITICAL_MODES = {"off": L.CRIT_OFF, "switch": L.CRIT_SWITCH, "forced": L.CRIT_FORCED}
STOPS = {"target": L.STOP_TARGET, "collision": L.STOP_COLLISION,
         "critical": L.STOP_CRITICAL, "above": L.STOP_ABOVE}

# Tight default tolerances: the reference runs of the benchmark tasks.
REFERENCE_RTOL = 1e-10
REFERENCE_ATOL = 1e-12


def _choice(name: str, value: str, allowed: dict) -> int:
    if value not in allowed:
        raise ValueError(f"{name} must be one of {sorted(allowed)}, got {value!r}")
    return allowed[value]


def check_state(name: str, value, size: int = L.N_STATE) -> np.ndarray:
    """A finite float vector of the given size, or a ValueError naming the argument."""
    try:
        array = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {size} finite numbers, got {value!r}") from None
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be {size} finite numbers, got {value!r}")
    return array


def check_tolerance(name: str, value: float) -> float:
    if not (isinstance(value, (int, float)) and np.isfinite(value) and 0 < value < 1):
        raise ValueError(f"{name} must be a number in (0, 1), got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Event:
    time: float
    """[s]"""
    kind: str
    """One of layout.EVENT_NAMES' values."""
    axis: int | None = None
    """0-based axis for current-limit events."""


@dataclass
class Trajectory:
    """A simulated run: samples at every accepted step and at every event."""

    t: np.ndarray
    """Times [s], shape (n,)."""
    x: np.ndarray
    """States (q1, q2, q3, v1, v2, v3, I1, I2, I3, E), shape (n, 10); E is the electrical
    energy drawn since the start [J]."""
    voltage: np.ndarray
    """Armature voltages [V], shape (n, 3)."""
    events: list[Event]
    params: ScaraParams
    status: str
    """"target", "collision", "critical", "above" (stop events), "end" or an error."""
    stats: dict = field(default_factory=dict)
    """rhs evaluations, steps, rejected steps, runtime [s]."""

    @property
    def q(self) -> np.ndarray:
        return self.x[:, 0:3]

    @property
    def rates(self) -> np.ndarray:
        return self.x[:, 3:6]

    @property
    def currents(self) -> np.ndarray:
        return self.x[:, 6:9]

    @property
    def energy(self) -> np.ndarray:
        """Electrical energy drawn since the start, int sum U_i I_i dt [J]."""
        return self.x[:, 9]

    @property
    def tip(self) -> np.ndarray:
        """Tool tip (x, y, z) [m], shape (n, 3)."""
        return tip_positions(self.q, self.params)

    @property
    def end_time(self) -> float:
        return float(self.t[-1])

    def times(self, kind: str) -> list[float]:
        return [e.time for e in self.events if e.kind == kind]

    def first(self, kind: str) -> float | None:
        found = self.times(kind)
        return found[0] if found else None

    @property
    def reach_time(self) -> float | None:
        """First time all |q_i - q^_i| < acc [s], or None."""
        return self.first("target_reached")

    @property
    def collision_time(self) -> float | None:
        return self.first("collision")

    @staticmethod
    def concatenate(parts: Sequence["Trajectory"], status: str | None = None) -> "Trajectory":
        stats = {}
        for part in parts:
            for key, value in part.stats.items():
                stats[key] = stats.get(key, 0) + value
        return Trajectory(
            t=np.concatenate([p.t for p in parts]),
            x=np.concatenate([p.x for p in parts]),
            voltage=np.concatenate([p.voltage for p in parts]),
            events=[e for p in parts for e in p.events],
            params=parts[0].params,
            status=status or parts[-1].status,
            stats=stats,
        )


_STATUS_NAMES = {
    L.STATUS_END: "end", L.STATUS_MAX_STEPS: "max_steps",
    L.STATUS_STEP_UNDERFLOW: "step_underflow", L.STATUS_NOT_FINITE: "not_finite",
}
_STOP_NAMES = {L.EV_TARGET_IN: "target", L.EV_COLLISION: "collision",
               L.EV_CRITICAL_ON: "critical", L.EV_ABOVE: "above"}


class Simulator:
    """One configured hybrid simulation of the C11 model.

    Arguments:
        params: the parameter tree.
        form: "explicit" (analytic inverse) or "implicit" (linear solve).
        control: "pd" (command = PD set-point q^) or "voltage" (command = U / limit).
        critical: "off", "switch" (the obstacle rule evaluated at every instant) or
            "forced" (the decelerated model throughout).
        widen: the voltage limit is Umax_wide while critical.
        decelerate: q1' = dec v1, q2' = dec v2 while critical (the seed's rule).
        wall: locate crossings of the wall plane (collisions).
        stop: stop events, a subset of ("target", "collision", "critical", "above").
        rtol, atol: error tolerances, with scipy's meaning.
        max_step: largest integration step [s].
        record: keep samples (capacity); 0 for none.
    """

    def __init__(self, params: ScaraParams = DEFAULT_PARAMS, *, form: str = "explicit",
                 control: str = "pd", critical: str = "off", widen: bool = False,
                 decelerate: bool = False, wall: bool = False, stop: Sequence[str] = ("target",),
                 rtol: float = REFERENCE_RTOL, atol: float = REFERENCE_ATOL,
                 max_step: float = 0.01, max_steps: int = 2_000_000, record: int = 200_000,
                 max_events: int = 10_000) -> None:
        if not isinstance(params, ScaraParams):
            raise TypeError(f"params must be a ScaraParams, got {type(params).__name__}")
        self.params = params
        self.p = params.to_array()
        self.config = np.zeros(L.N_CONFIG, dtype=np.int64)
        self.config[L.C_FORM] = _choice("form", form, FORMS)
        self.config[L.C_CONTROL] = _choice("control", control, CONTROLS)
        self.config[L.C_CRITICAL] = _choice("critical", critical, CRITICAL_MODES)
        self.config[L.C_WIDEN] = int(bool(widen))
        self.config[L.C_DEC] = int(bool(decelerate))
        self.config[L.C_WALL] = int(bool(wall))
        mask = 0
        for name in stop:
            mask |= _choice("stop", name, STOPS)
        self.config[L.C_STOP] = mask
        self.config[L.C_MAX_STEPS] = int(max_steps)
        self.rtol = check_tolerance("rtol", rtol)
        self.atol = check_tolerance("atol", atol)
        if not (np.isfinite(max_step) and max_step > 0):
            raise ValueError(f"max_step must be a finite number > 0 [s], got {max_step!r}")
        self.modes = np.zeros(L.N_MODES, dtype=np.int64)
        self.step_state = np.array([0.0, float(max_step)])
        self.counters = np.zeros(L.N_COUNTERS, dtype=np.int64)
        self.rec_t = np.empty(record)
        self.rec_x = np.empty((record, L.N_STATE))
        self.rec_u = np.empty((record, 3))
        self.ev_t = np.empty(max_events)
        self.ev_code = np.empty(max_events, dtype=np.int64)
        self.ev_axis = np.empty(max_events, dtype=np.int64)
        self.x = np.zeros(L.N_STATE)
        self.t = 0.0
        self.command = np.zeros(3)

    def reset(self, x0, t0: float = 0.0, command=None) -> None:
        self.x = check_state("initial state", x0).copy()
        self.t = float(t0)
        if command is not None:
            self.command = check_state("command", command, 3).copy()
        initial_modes(self.x, self.p, self.command, self.config, self.modes)
        self.step_state[0] = 0.0
        self.counters[:] = 0

    def advance(self, t_end: float, command=None) -> int:
        """Integrate to t_end or the first stop event; returns the kernel status."""
        if command is not None:
            self.command = check_state("command", command, 3).copy()
        status, self.t = integrate(
            self.x, self.t, float(t_end), self.p, self.command, self.config, self.modes,
            self.rtol, self.atol, self.step_state, self.rec_t, self.rec_x, self.rec_u,
            self.ev_t, self.ev_code, self.ev_axis, self.counters)
        return status

    def status_name(self, status: int) -> str:
        if status == L.STATUS_STOPPED:
            return _STOP_NAMES[int(self.counters[L.K_LAST_EVENT])]
        return _STATUS_NAMES[status]

    @property
    def critical(self) -> bool:
        return bool(self.modes[L.M_CRITICAL])

    def events(self, since: int = 0) -> list[Event]:
        n = min(int(self.counters[L.K_EVENTS]), self.ev_t.shape[0])
        return [Event(float(self.ev_t[i]), L.EVENT_NAMES[int(self.ev_code[i])],
                      int(self.ev_axis[i]) if self.ev_axis[i] >= 0 else None)
                for i in range(since, n)]

    def trajectory(self, status: int, runtime: float = 0.0) -> Trajectory:
        n = int(self.counters[L.K_RECORDS])
        if n >= self.rec_t.shape[0] and self.t > self.rec_t[n - 1]:
            raise RuntimeError("record capacity exhausted; raise Simulator(record=...)")
        return Trajectory(
            t=self.rec_t[:n].copy(), x=self.rec_x[:n].copy(), voltage=self.rec_u[:n].copy(),
            events=self.events(), params=self.params, status=self.status_name(status),
            stats={"rhs": int(self.counters[L.K_RHS]), "steps": int(self.counters[L.K_STEPS]),
                   "rejected": int(self.counters[L.K_REJECTED]), "runtime": runtime})


def tip_positions(q: np.ndarray, params: ScaraParams) -> np.ndarray:
    """Vectorized tip_position for joint positions q of shape (n, 3) -> (n, 3) [m]."""
    q = np.asarray(q, dtype=float)
    l1, l2 = params.arm.link1_length, params.arm.link2_length
    return np.stack([l1 * np.cos(q[:, 0]) + l2 * np.cos(q[:, 0] + q[:, 1]),
                     l1 * np.sin(q[:, 0]) + l2 * np.sin(q[:, 0] + q[:, 1]),
                     q[:, 2]], axis=1)


def start_state(params: ScaraParams, q0=None) -> np.ndarray:
    """Joint positions q0 (default: the task's start), rates and currents zero."""
    x0 = np.zeros(L.N_STATE)
    x0[:3] = params.task.start if q0 is None else check_state("q0", q0, 3)
    return x0
