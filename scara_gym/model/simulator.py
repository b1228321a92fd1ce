"""Python side of the compiled integrator: configuration, trajectories and events.

`Simulator` owns the arrays one simulation needs and advances a state in
chunks (the environment calls it once per control step); `simulate` runs
one segment and returns a `Trajectory`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from scara_gym.model import checks, records as R
from scara_gym.model.checks import UserTypeError
from scara_gym.model.dynamics import tip_positions
from scara_gym.model.integrator import advance, start
from scara_gym.model.params import DEFAULT_PARAMS, ScaraParams, resolve_params

FORMS = {"explicit": R.FORM_EXPLICIT, "implicit": R.FORM_IMPLICIT}
CONTROLS = {"pd": R.CONTROL_PD, "voltage": R.CONTROL_VOLTAGE}
CRITICAL_MODES = {"off": R.CRIT_OFF, "switch": R.CRIT_SWITCH, "forced": R.CRIT_FORCED}
STOPS = {"target": R.STOP_TARGET, "collision": R.STOP_COLLISION,
         "critical": R.STOP_CRITICAL, "above": R.STOP_ABOVE}

# Tight default tolerances: the reference runs of the benchmark tasks.
REFERENCE_RTOL = 1e-10
REFERENCE_ATOL = 1e-12


def _choice(name: str, value: str, allowed: dict) -> int:
    return allowed[checks.choice(name, value, allowed)]


def check_state(name: str, value, size: int = R.N_STATE) -> np.ndarray:
    """A finite float vector of the given size, or an error naming the argument."""
    return checks.real_array(name, value, (size,)).copy()


def check_tolerance(name: str, value: float) -> float:
    """rtol or atol inside its allowed range (see `scara_gym.model.checks`)."""
    return checks.tolerance(name, value)


@dataclass(frozen=True)
class Event:
    """A logged event of a simulated run: when, what, and on which axis."""
    time: float
    """[s]"""
    kind: str
    """One of records.EVENT_NAMES' values."""
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
        """Joint positions (q1, q2, q3) [rad, rad, m], shape (n, 3)."""
        return self.x[:, 0:3]

    @property
    def rates(self) -> np.ndarray:
        """Joint rates (v1, v2, v3) [rad/s, rad/s, m/s], shape (n, 3)."""
        return self.x[:, 3:6]

    @property
    def currents(self) -> np.ndarray:
        """Armature currents (I1, I2, I3) [A], shape (n, 3)."""
        return self.x[:, 6:9]

    @property
    def energy(self) -> np.ndarray:
        """Electrical energy drawn since the start, int sum U_i I_i dt [J]."""
        return self.x[:, 9]

    @property
    def tip(self) -> np.ndarray:
        """Tool tip (x, y, z) [m], shape (n, 3)."""
        return tip_positions(np.ascontiguousarray(self.q), self.params.to_record())

    @property
    def end_time(self) -> float:
        """The last sample's time [s]."""
        return float(self.t[-1])

    def times(self, kind: str) -> list[float]:
        """The times [s] of the events of one kind (an EVENT_NAMES value)."""
        return [e.time for e in self.events if e.kind == kind]

    def first(self, kind: str) -> float | None:
        """The first time [s] of an event of one kind, or None."""
        found = self.times(kind)
        return found[0] if found else None

    @property
    def reach_time(self) -> float | None:
        """First time all |q_i - q^_i| < acc [s], or None."""
        return self.first("target_reached")

    @property
    def collision_time(self) -> float | None:
        """The first collision's time [s], or None."""
        return self.first("collision")

    @staticmethod
    def concatenate(parts: Sequence[Trajectory], status: str | None = None) -> Trajectory:
        """One trajectory of consecutive parts (their samples, events and summed stats); status: the last part's unless given."""
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


MAX_STEPS_LIMIT = 10**9


class SimulationError(RuntimeError):
    """An integration that could not go on; the message names the cause."""


def failure_message(status: int, robot, config, params: ScaraParams) -> str:
    """Why an integration stopped with a negative status, and what to change."""
    t, h = float(robot["t"]), float(robot["step_size"])
    time_constant = min(axis.inductance / axis.resistance for axis in params.axes)
    stiffness = (f"the smallest electrical time constant L/R is {time_constant:.3g} s; "
                 f"rtol = {float(config['rtol']):g}, atol = {float(config['atol']):g}")
    if status == R.STATUS_MAX_STEPS:
        return (f"integration stopped at t = {t:.6f} s: max_steps = {int(config['max_steps'])} step "
                f"attempts used up with the step size at {h:.3g} s. The model is too stiff or too fast "
                f"for these parameters and tolerances ({stiffness}); loosen the tolerances, change the "
                f"parameters, or raise max_steps")
    if status == R.STATUS_STEP_UNDERFLOW:
        return (f"integration stopped at t = {t:.6f} s: the step size fell to {h:.3g} s, below the "
                f"resolution of t, while the error estimate stayed too large ({stiffness}); the "
                f"tolerances are too tight for float64 or the right-hand side jumps there")
    if status == R.STATUS_NOT_FINITE:
        return (f"integration stopped at t = {t:.6f} s: the state became infinite or NaN even at a "
                f"step size of {h:.3g} s; the parameters drive the model out of float64's range")
    return f"integration failed with status {status} at t = {t:.6f} s"


STATUS_NAMES = {
    R.STATUS_END: "end", R.STATUS_MAX_STEPS: "max_steps",
    R.STATUS_STEP_UNDERFLOW: "step_underflow", R.STATUS_NOT_FINITE: "not_finite",
}
STOP_NAMES = {R.EV_TARGET_IN: "target", R.EV_COLLISION: "collision",
              R.EV_CRITICAL_ON: "critical", R.EV_ABOVE: "above"}


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
        rtol: relative error tolerance, with scipy's meaning.
        atol: absolute error tolerance, with scipy's meaning.
        exact_switches: the PD saturation a located mode switch, and every mode switch
            searched inside each step (one that starts and ends inside a step is found);
            False (the default, the behaviour of 0.1 and 0.2): switches are seen at the ends
            of steps, and the saturation is a kink left to step-size control.
        max_step: largest integration step [s].
        record: keep samples (capacity); 0 for none.
        tolerance_weights: None, or a dict from state groups ("q", "rate", "current", "energy")
            to a factor in [1e-3, 1e3] on both tolerances for that group's components.
    """

    def __init__(self, params: ScaraParams = DEFAULT_PARAMS, *, form: str = "explicit",
                 control: str = "pd", critical: str = "off", widen: bool = False,
                 decelerate: bool = False, wall: bool = False, stop: Sequence[str] = ("target",),
                 rtol: float = REFERENCE_RTOL, atol: float = REFERENCE_ATOL,
                 exact_switches: bool = False, max_step: float = 0.01, max_steps: int = 2_000_000,
                 record: int = 200_000, max_events: int = 10_000, tolerance_weights: dict | None = None) -> None:
        self.params = params = resolve_params(params)
        self.p = np.array([params.to_record()], dtype=R.PARAMS)
        self.config = np.zeros(1, dtype=R.CONFIG)
        config = self.config[0]
        config["form"] = _choice("form", form, FORMS)
        config["control"] = _choice("control", control, CONTROLS)
        config["critical_rule"] = _choice("critical", critical, CRITICAL_MODES)
        config["widen"] = checks.flag("widen", widen)
        config["decelerate"] = checks.flag("decelerate", decelerate)
        config["wall"] = checks.flag("wall", wall)
        if isinstance(stop, str) or not isinstance(stop, (tuple, list, set, frozenset)):
            raise UserTypeError(f"stop must be a tuple of stop events among {sorted(STOPS)}, got {stop!r}")
        mask = 0
        for name in stop:
            mask |= _choice("stop", name, STOPS)
        config["stops"] = mask
        config["max_steps"] = checks.integer("max_steps", max_steps, 1, MAX_STEPS_LIMIT)
        config["rtol"] = self.rtol = check_tolerance("rtol", rtol)
        config["atol"] = self.atol = check_tolerance("atol", atol)
        config["exact_switches"] = checks.flag("exact_switches", exact_switches)
        config["tolerance_weights"] = checks.tolerance_weights(tolerance_weights, R.STATE_GROUPS)
        self.robots = np.zeros(1, dtype=R.ROBOT)
        self.robot = self.robots[0]
        self.robot["max_step"] = checks.real("max_step", max_step, 0.0, 1.0, unit="s", low_open=True)
        self.samples = np.zeros(checks.integer("record", record, 0, 10**8), dtype=R.SAMPLE)
        self.log = np.zeros(checks.integer("max_events", max_events, 1, 10**8), dtype=R.EVENT)
        self._started = False

    @property
    def x(self) -> np.ndarray:
        """The state vector (a view: (q1, q2, q3, v1, v2, v3, I1, I2, I3, E))."""
        return self.robot["x"]

    @property
    def t(self) -> float:
        """The simulator's time [s]."""
        return float(self.robot["t"])

    @property
    def command(self) -> np.ndarray:
        """The command held: the set-point q^ ("pd") or the voltages ("voltage"), shape (3,)."""
        return self.robot["command"]

    def reset(self, x0, t0: float = 0.0, command=None) -> None:
        """Start from the state x0 at time t0 [s] (optionally with a command); the counters and the log start empty."""
        robot = self.robot
        x0 = check_state("initial state", x0)
        t0 = checks.real("t0", t0, unit="s")
        command = None if command is None else check_state("command", command, 3)
        robot["x"] = x0
        robot["t"] = t0
        if command is not None:
            robot["command"] = command
        self._started = True
        start(self.robots, self.p, self.config)
        robot["step_size"] = 0.0
        for counter in ("n_samples", "n_events", "n_rhs", "n_steps", "n_rejected", "stop_event", "n_collisions"):
            robot[counter] = 0
        robot["reach_time"] = np.nan

    def advance(self, t_end: float, command=None) -> int:
        """Integrate to t_end or the first stop event; returns the kernel status. Raises
        `SimulationError`, naming the cause, when the integration fails.
        """
        if not self._started:
            raise RuntimeError("call reset(x0) before advance()")
        t_end = checks.real("t_end", t_end, self.t, unit="s (not before the simulator's time)")
        if command is not None:
            self.robot["command"] = check_state("command", command, 3)
        samples = self.samples if len(self.samples) else None
        status = advance(self.robots, self.p, self.config, t_end, self.log, samples)
        if status < 0:
            raise SimulationError(failure_message(status, self.robots[0], self.config[0], self.params))
        return status

    def status_name(self, status: int) -> str:
        """The name of a status advance returned (the stop event's, where it stopped on one)."""
        if status == R.STATUS_STOPPED:
            return STOP_NAMES[int(self.robot["stop_event"])]
        return STATUS_NAMES[status]

    @property
    def critical(self) -> bool:
        """Whether the tip is inside the critical band of the wall now."""
        return bool(self.robot["critical"])

    def events(self, since: int = 0) -> list[Event]:
        """The logged events; raises when the log overflowed (the stop status and the
        robot's counters are complete either way).
        """
        n = int(self.robot["n_events"])
        if n > len(self.log):
            raise RuntimeError(f"event log overflowed: {n} events, capacity {len(self.log)}; "
                               f"raise Simulator(max_events=...)")
        log = self.log[since:n]
        return [Event(float(e["time"]), R.EVENT_NAMES[int(e["code"])],
                      int(e["axis"]) if e["axis"] >= 0 else None) for e in log]

    def trajectory(self, status: int, runtime: float = 0.0) -> Trajectory:
        """The run recorded so far as a Trajectory, with the status advance returned and the runtime [s]."""
        n = int(self.robot["n_samples"])
        samples = self.samples[:n]
        if n and n >= len(self.samples) and self.t > samples["t"][-1]:
            raise RuntimeError("record capacity exhausted; raise Simulator(record=...)")
        robot = self.robot
        return Trajectory(
            t=samples["t"].copy(), x=samples["x"].copy(), voltage=samples["voltage"].copy(),
            events=self.events(), params=self.params, status=self.status_name(status),
            stats={"rhs": int(robot["n_rhs"]), "steps": int(robot["n_steps"]),
                   "rejected": int(robot["n_rejected"]), "runtime": runtime})


def start_state(params: ScaraParams, q0=None) -> np.ndarray:
    """Joint positions q0 (default: the task's start), rates and currents zero."""
    params = resolve_params(params)
    x0 = np.zeros(R.N_STATE)
    x0[R.Q:R.Q + 3] = params.task.start if q0 is None else check_state("q0", q0, 3)
    return x0
