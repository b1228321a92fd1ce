"""Nonlinear model-predictive control: a receding-horizon optimal-control problem solved at
every control step, on the symbolic model (`scara_gym.model.symbolic`).

    scara-agents evaluate --policies mpc --control-mode voltage --condition c11-starts
    scara-agents evaluate --policies mpc --control-mode pd --condition c11-starts

The problem, on the environment's control grid (``MPCConfig``):

- the voltages U_k held over each 0.01 s step, as the environment applies them, with
  |U_k| <= the step's voltage limit (Umax, or Umax_wide where the step is critical);
- the model with free currents, one Radau IIA collocation element of degree 3 per step (the
  currents' time constants, 0.5-1.9 ms, are far below a step: the collocation is L-stable),
  with |I| <= Imax at every collocation point, from the measured state (rates and currents
  from the observation, currents clipped to their limits);
- the wall as a sequence of phases, as the minimum-time reference has them: a step is
  "free" (the tip ``wall_margin`` clear of the wall plane, normal limits), "critical" (the tip
  inside the critical band, ``wall_margin`` clear of the plane, q3 below h_obs: the widened
  limits) or "above" (q3 at least ``height_margin`` above h_obs, where the wall no longer
  matters); below h_obs the tip's approach to the wall is rate-limited (``approach_rate``).
  The phase of each step comes from the previous solution's prediction (a step whose tip
  comes within ``band_capture`` of the band is critical, one whose q3 reaches h_obs +
  height_margin is above, in that order), so that the problem stays smooth; the wall
  constraints are soft (an exact L1 penalty) so that a measured state that violates them
  still has a solution;
- the terminal rule: where the horizon ends below h_obs, axes 1 and 2 end at rest with zero
  current (a set the arm can stay in with axes 1 and 2 unpowered, so the next problem is
  always feasible and the wall stays clear when the horizon ends before the target);
- the cost: squared joint errors to the target, each in seconds at its axis' top speed (the
  back-EMF caps axis i at Umax_i / (kT_i u_i)), a small voltage term, the penalties;
- IPOPT, warm-started from the previous solution and its multipliers shifted by one step.

The wall's plane and height are read from the observation (``wall_distance``,
``height_margin``), like every policy's; the dynamics are those of the model's parameters
(``params``: the nominal robot unless given, so that a shifted robot is a model mismatch).
Each solve's wall-clock time is kept in ``solve_times``, the solves IPOPT did not converge in
``failures`` (the plan it stopped at is used).

In a "pd"-mode environment the MPC plans the same voltages and commands the set-point for which
the PD law gives them at the step's start (the env's ``pd_setpoint``: a saturated voltage asks
for a set-point past saturation). Within the step the law's voltage then follows the state
(P q' + D q'' volts per second where it is not saturated), so the plan is applied exactly only
where it saturates; the next step's solve starts from the measured state. Planning the
set-points themselves, with the saturated law inside the collocation, was tried and dropped:
where the law saturates its voltage does not depend on the set-point, a degenerate problem on
which IPOPT stalled (docs/optimal-and-mpc.md, "The pd mode").
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from agents.policies.optimal.transcription import radau_coefficients
from scara_gym import DEFAULT_PARAMS, ScaraParams
from scara_gym.envs import OBSERVATION_LAYOUT
from scara_gym.model import checks
from scara_gym.model.dynamics import tip_positions
from scara_gym.model.symbolic import symbolic_model

Q, RATES, CURRENTS, TARGET_ERROR = (OBSERVATION_LAYOUT[n] for n in ("q", "rate", "current", "target_error"))
TIP_X, WALL_DISTANCE, HEIGHT_MARGIN, CRITICAL = (OBSERVATION_LAYOUT[n] for n in
                                                 ("tip_x", "wall_distance", "height_margin", "critical"))
FREE, BAND, ABOVE = 0, 1, 2  # the phases of a step
INF = np.inf


@dataclass(frozen=True)
class MPCConfig:
    """The receding-horizon problem (module docstring)."""

    horizon: int = 25
    """control steps predicted (0.25 s at 0.01 s)"""
    wall_margin: float = 5e-3
    """m, the tip's least distance from the wall plane while below h_obs (the shield's margin)"""
    approach_rate: float = 20.0
    """1/s, below h_obs the tip closes on the wall at most this rate times its clearance beyond
    ``wall_margin`` (d/dt clearance >= -rate (clearance - margin): an exponential approach, so
    that a robot that brakes less than the model still stops short of the wall)"""
    band_inset: float = 1e-3
    """m, a critical step keeps the tip this far inside the critical band's outer edge"""
    band_capture: float = 5e-3
    """m, a step whose predicted tip comes this close to the critical band is planned inside it"""
    height_margin: float = 2e-3
    """m, q3 above h_obs in the steps planned above the wall"""
    weights: tuple[float, float, float] | None = None
    """cost weights of the squared joint errors [s^2/rad^2, s^2/rad^2, s^2/m^2]; None: 1 / v_max_i^2,
    v_max_i = Umax_i / (kT_i u_i) the speed the back-EMF allows at Umax (each error in seconds at
    the axis' top speed: the time it still costs)"""
    voltage_weight: float = 1e-6
    """cost weight of (U / Umax)^2 per step"""
    penalty: float = 1e4
    """exact-penalty weight of a wall constraint's violation [1/m]"""
    max_iter: int = 200
    tol: float = 1e-6
    shift_multipliers: bool = True
    """warm-start the multipliers too (shifted like the plan)"""
    first_passes: int = 4
    """solves of the first step of an episode, each with the phases of the previous one"""
    params: ScaraParams | None = None
    """the model's parameters (None: the nominal robot, DEFAULT_PARAMS)"""
    solver: str = "ipopt"
    """the NLP solver: CasADi's IPOPT (the structure-exploiting fatrop was slower on this problem:
    docs/optimal-and-mpc.md, "Solve time")"""
    solver_options: dict = field(default_factory=dict)
    """further options of the CasADi solver (e.g. {"ipopt.print_level": 5})"""

    def __post_init__(self) -> None:
        checks.integer("horizon", self.horizon, 2, 500)
        for name, high in (("wall_margin", 0.05), ("band_inset", 0.01), ("band_capture", 0.05), ("height_margin", 0.05)):
            checks.real(name, getattr(self, name), 0.0, high)
        if self.weights is not None:
            object.__setattr__(self, "weights", tuple(checks.real_array("weights", self.weights, (3,), low=0.0)))
        for name in ("voltage_weight", "penalty", "tol", "approach_rate"):
            checks.real(name, getattr(self, name), 0.0, 1e12, low_open=True)
        checks.integer("max_iter", self.max_iter, 1, 100_000)
        checks.choice("solver", self.solver, ("ipopt",))
        checks.integer("first_passes", self.first_passes, 1, 100)
        if not isinstance(self.solver_options, dict):
            raise TypeError(f"solver_options must be a dict of CasADi solver options, got {self.solver_options!r}")
        if self.params is not None and not isinstance(self.params, ScaraParams):
            raise TypeError(f"params must be a ScaraParams or None, got {type(self.params).__name__}")


class MPCPolicy:
    """Nonlinear MPC in a "voltage"- or "pd"-mode environment (module docstring)."""

    name = "mpc"

    def __init__(self, env, config: MPCConfig | None = None) -> None:
        if config is not None and not isinstance(config, MPCConfig):
            raise TypeError(f"config must be an MPCConfig or None, got {config!r}")
        self.env = env.unwrapped
        self.mode = self.env.control_mode
        self.config = config = MPCConfig() if config is None else config
        self.params = config.params if config.params is not None else DEFAULT_PARAMS
        obstacle = self.params.obstacle
        self.critical_distance = obstacle.critical_distance
        if config.wall_margin + config.band_inset >= self.critical_distance:
            raise ValueError(f"wall_margin + band_inset = {config.wall_margin + config.band_inset} m leaves no "
                             f"critical band: it must be below the critical distance {self.critical_distance} m")
        self.record = self.params.to_record()
        self.voltage_limit = self.params.voltage_limits
        self.wide_limit = np.array(obstacle.wide_voltage_limits, dtype=float)
        self.current_limit = np.array([a.current_limit for a in self.params.axes])
        self.control_dt = float(self.env.control_dt)
        top_speed = self.voltage_limit / np.array([a.torque_constant * a.gear_ratio for a in self.params.axes])
        self.weights = np.array(config.weights) if config.weights is not None else 1.0 / top_speed**2
        self._build()
        self.solve_times: list[float] = []
        self.failures = 0
        self.reset()

    # the problem, built once ------------------------------------------------------------
    # decision variables: the measured state X_0, then stage by stage [U_k, XC_k, S_k]: the step's
    # voltages, its three collocation states (the last one is the step's end, the next stage's
    # start: Radau's last point is the step's end, so no separate state or continuity row) and its
    # four slacks (tip below / above its bounds, q3 below / above). The currents' limits are
    # bounds on the collocation states, not constraint rows.
    HEAD = 9
    STAGE = 3 + 27 + 4
    VOLTAGES, SLACKS = slice(0, 3), slice(30, 34)  # within a stage
    POINTS = (3, 12, 21)  # where each collocation state starts within a stage (the last: the step's end)
    ROWS = 27 + 9  # constraints per stage: collocation, then (clearance, height, approach) per point

    def _build(self) -> None:
        import casadi as ca

        c, n = self.config, self.config.horizon
        self.model = model = symbolic_model(self.params, control="voltage")
        _, C = radau_coefficients(3)
        target = ca.SX.sym("target", 3)
        wall_x, wall_height, side = ca.SX.sym("wall_x"), ca.SX.sym("wall_height"), ca.SX.sym("side")
        w = ca.SX.sym("w", self.HEAD + self.STAGE * n)
        stage = [w[self.HEAD + self.STAGE * k:self.HEAD + self.STAGE * (k + 1)] for k in range(n)]
        end = self.POINTS[-1]
        X = [w[:self.HEAD]] + [s[end:end + 9] for s in stage]
        weights = ca.DM(self.weights)
        cost, g = 0, []
        for k in range(n):
            U, S = stage[k][self.VOLTAGES], stage[k][self.SLACKS]
            points = [X[k]] + [stage[k][start:start + 9] for start in self.POINTS]
            for j in range(1, 4):
                slope = sum(C[r, j] * points[r] for r in range(4))
                g.append(slope - self.control_dt * model.free(points[j], U))
            for j in range(1, 4):
                q, rates = points[j][:3], points[j][3:6]
                clearance = side * (model.tip(q)[0] - wall_x)
                approach = side * ca.jtimes(model.tip(q)[0], q, rates)  # d clearance / dt
                g.append(ca.vertcat(clearance + S[0] - S[1], points[j][2] - wall_height + S[2] - S[3],
                                    approach + c.approach_rate * (clearance - c.wall_margin) + S[0]))
            error = X[k + 1][:3] - target
            cost += ca.sum1(weights * error**2)
            cost += c.voltage_weight * ca.sum1((U / self.voltage_limit) ** 2)
            cost += c.penalty * ca.sum1(S) + 1e2 * c.penalty * ca.sum1(S**2)
        g.append(ca.vertcat(X[n][3], X[n][4], X[n][6], X[n][7]))
        nlp = {"x": w, "p": ca.vertcat(target, wall_x, wall_height, side), "f": cost, "g": ca.vertcat(*g)}
        options = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.max_iter": c.max_iter,
                   "ipopt.tol": c.tol, "ipopt.warm_start_init_point": "yes", "ipopt.mu_strategy": "adaptive",
                   "ipopt.warm_start_bound_push": 1e-6, "ipopt.warm_start_mult_bound_push": 1e-6, **c.solver_options}
        self.solver = ca.nlpsol("mpc", c.solver, nlp, options)
        self.predict = ca.Function("predict", [w], [ca.horzcat(*X[1:])])  # the state at every step's end

    # bounds of one solve -----------------------------------------------------------------
    def _bounds(self, phases: np.ndarray, first_limit: np.ndarray, x0: np.ndarray):
        c, n = self.config, self.config.horizon
        limits = np.where(phases[:, None] == BAND, self.wide_limit[None, :], self.voltage_limit[None, :])
        limits[0] = first_limit
        lbx, ubx = np.full((n, self.STAGE), -INF), np.full((n, self.STAGE), INF)
        lbx[:, self.VOLTAGES], ubx[:, self.VOLTAGES] = -limits, limits
        for start in self.POINTS:  # the currents at the collocation points
            lbx[:, start + 6:start + 9], ubx[:, start + 6:start + 9] = -self.current_limit, self.current_limit
        lbx[:, self.SLACKS] = 0.0
        lbx, ubx = np.append(x0, lbx.ravel()), np.append(x0, ubx.ravel())  # X_0: the measured state
        lower, upper = [], []
        band = (c.wall_margin, self.critical_distance - c.band_inset)
        for phase in phases:
            if phase == FREE:
                tip, height = (c.wall_margin, INF), (-INF, INF)
            elif phase == BAND:
                tip, height = band, (-INF, INF)
            else:
                tip, height = (-INF, INF), (c.height_margin, INF)
            approach = -INF if phase == ABOVE else 0.0
            lower += [np.zeros(27), [tip[0], height[0], approach] * 3]
            upper += [np.zeros(27), [tip[1], height[1], INF] * 3]
        terminal = np.zeros(4) if phases[-1] != ABOVE else np.full(4, INF)
        lower.append(-terminal)
        upper.append(terminal)
        return lbx, ubx, np.concatenate(lower), np.concatenate(upper)

    def _phases(self, ends: np.ndarray, wall_x: float, wall_height: float) -> np.ndarray:
        """The phase of every step from the predicted state at its end (module docstring)."""
        c = self.config
        phases = np.full(len(ends), FREE)
        tip = tip_positions(ends[:, :3], self.record)[:, 0]
        above = ends[:, 2] >= wall_height + c.height_margin - 1e-4
        first_above = int(np.argmax(above)) if above.any() else len(ends)
        in_band = self.side * (tip - wall_x) <= self.critical_distance - c.band_inset + c.band_capture
        first_band = int(np.argmax(in_band[:first_above])) if in_band[:first_above].any() else first_above
        phases[first_band:first_above] = BAND
        phases[first_above:] = ABOVE
        return phases

    # the policy ----------------------------------------------------------------------------
    def reset(self) -> None:
        self.guess = None
        self.multipliers = None
        self.side = None

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=float)
        x0 = np.concatenate([obs[Q], obs[RATES], np.clip(obs[CURRENTS], -self.current_limit, self.current_limit)])
        target = obs[Q] + obs[TARGET_ERROR]
        wall_x = obs[TIP_X] - obs[WALL_DISTANCE]
        wall_height = obs[Q][2] - obs[HEIGHT_MARGIN]
        critical = obs[CRITICAL] > 0.5
        first_limit = self.wide_limit if critical else self.voltage_limit
        passes = 1
        if self.guess is None:
            self.side = 1.0 if obs[WALL_DISTANCE] >= 0 else -1.0
            n = self.config.horizon
            block = np.concatenate([np.zeros(3), np.tile(x0, 3), np.zeros(4)])
            self.guess = np.append(x0, np.tile(block, n))
            passes = self.config.first_passes
        parameters = np.concatenate([target, [wall_x, wall_height, self.side]])
        for _ in range(passes):
            ends = np.array(self.predict(self.guess)).T
            phases = self._phases(ends, wall_x, wall_height)
            lbx, ubx, lbg, ubg = self._bounds(phases, first_limit, x0)
            guess = np.clip(self.guess, lbx, ubx)
            started = time.perf_counter()
            kwargs = {} if self.multipliers is None else {"lam_x0": self.multipliers[0], "lam_g0": self.multipliers[1]}
            solution = self.solver(x0=guess, p=parameters, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg, **kwargs)
            self.solve_times.append(time.perf_counter() - started)
            if not self.solver.stats()["success"]:
                self.failures += 1
            self.guess = np.array(solution["x"]).ravel()
            self.multipliers = (np.array(solution["lam_x"]).ravel(), np.array(solution["lam_g"]).ravel())
        action = np.clip(self.guess[self.HEAD:][self.VOLTAGES] / first_limit, -1.0, 1.0)
        if self.mode == "pd":  # the set-point for which the PD law gives these voltages at the step's start
            action = self.env.setpoint_action(obs, self.env.pd_setpoint(obs, action))
        self._shift()
        return action

    def _shift(self) -> None:
        """The warm start of the next step: the plan one step on, its last step repeated (X_0 is
        the measured state, bound at the next solve)."""
        self.guess = self._shifted(self.guess, self.HEAD, self.STAGE)
        if self.multipliers is not None and self.config.shift_multipliers:
            lam_x, lam_g = self.multipliers
            self.multipliers = (self._shifted(lam_x, self.HEAD, self.STAGE), self._shifted(lam_g, 0, self.ROWS))
        else:
            self.multipliers = None

    def _shifted(self, values: np.ndarray, head: int, size: int) -> np.ndarray:
        """The ``head`` kept, the per-stage blocks of ``size`` after it moved one stage on (the last
        repeated), the tail kept."""
        n = self.config.horizon
        stages = values[head:head + size * n].reshape(n, size)
        return np.concatenate([values[:head], stages[1:].ravel(), stages[-1], values[head + size * n:]])


def solve_time_summary(times) -> dict:
    """Median, 95th percentile and worst of per-step solve times [s]."""
    times = np.asarray(times, dtype=float)
    return {"median": float(np.median(times)), "p95": float(np.percentile(times, 95)), "worst": float(times.max()),
            "solves": int(times.size)}
