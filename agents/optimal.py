"""Minimum-time reference: the fastest voltages the physics allows, by direct collocation.

    python -m agents.optimal                    # C11 target: both problems, replayed in the env
    python -m agents.optimal --target 1.5 2.5 0.25 --problem held

Two problems on the same model and the same transcription (CasADi, Radau collocation of
degree 3, IPOPT):

- ``"held"``: the environment's action interface in ``control_mode="voltage"``: the action
  a_k in [-1, 1]^3 is held over each 0.01 s control step and the voltage is a_k * limit,
  with limit = Umax, widened to Umax_wide from the located instant the tip becomes critical
  until q3 reaches h_obs. Its solution is an action sequence; :class:`OptimalPolicy`
  replays it in the environment, where success, collisions and the time are measured.
- ``"free"``: voltages free in time (piecewise constant on short elements whose lengths are
  decision variables through the free phase durations): the continuous-time bound of the
  spec (1.2217 s for the C11 target).

The minimum-time path has three phases, which fix the voltage limit and what the tip may
do: A (not critical: the tip beyond the critical band), B (critical: the tip inside the
band on the near side of the wall, q3 < h_obs; voltages widened), C (q3 >= h_obs: the wall
no longer matters). Their switching instants are decision variables; in the held problem
each falls inside a control step, which is split there (the action is shared by both parts).

The currents stay within their limits by the choice of voltages (a path constraint), so
the reference never leans on the model's current hold: every trajectory it finds is one
the environment can follow, and its time is an upper bound on the optimum under the
environment's rules, with the free problem's time a lower bound.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from scara_gym import DEFAULT_PARAMS, ScaraParams
from scara_gym.envs import OBSERVATION_LAYOUT

SOLUTIONS = Path(__file__).with_name("optimal_solutions")
PHASES = ("A", "B", "C")  # not critical, critical (widened), above the wall
Q, RATES, CURRENTS = (OBSERVATION_LAYOUT[name] for name in ("q", "rate", "current"))


@dataclass(frozen=True)
class CollocationConfig:
    """Transcription and safety margins of the minimum-time problems."""

    control_dt: float = 0.01
    """s, the environment's control step (held problem)"""
    elements_per_step: int = 4
    """collocation elements per control step (held problem)"""
    free_elements: tuple[int, int, int] = (60, 60, 160)
    """collocation elements of phases A, B, C (free problem)"""
    wall_margin: float = 1e-3
    """m, distance kept from the wall plane while below h_obs (the replay must not touch it)"""
    band_margin: float = 1e-4
    """final |q_i - q^_i| <= accuracy - band_margin (rad, m)"""
    ipopt_tol: float = 1e-8
    max_iter: int = 3000


def _values(params: ScaraParams):
    """The PARAMS record's fields as attributes (floats and arrays)."""
    from types import SimpleNamespace

    record = params.to_record()
    return SimpleNamespace(**{name: (float(record[name]) if np.ndim(record[name]) == 0 else np.array(record[name]))
                              for name in record.dtype.names})


def casadi_model(params: ScaraParams = DEFAULT_PARAMS):
    """CasADi functions of the C11 model with free currents (no hold: the problems keep the
    currents inside their limits): f(x, U) -> x' and the tip's x coordinate tip_x(x)."""
    import casadi as ca

    p = _values(params)
    x = ca.SX.sym("x", 9)
    u = ca.SX.sym("u", 3)
    q2, v1, v2, v3 = x[1], x[3], x[4], x[5]
    ku = [float(p.torque_constant[i] * p.gear_ratio[i]) for i in range(3)]
    torques = [ku[i] * x[6 + i] for i in range(3)]
    current_rates = [(u[i] - ku[i] * x[3 + i] - float(p.resistance[i]) * x[6 + i]) / float(p.inductance[i])
                     for i in range(3)]
    c, s = ca.cos(q2), ca.sin(q2)
    m11 = p.theta1 + 2.0 * p.theta2 * c + p.theta3
    m12 = p.theta2 * c + p.theta3
    m22 = p.theta3
    b1 = torques[0] + p.theta2 * (2.0 * v1 * v2 + v2 * v2) * s
    b2 = torques[1] - p.theta2 * v1 * v1 * s
    det = p.theta1 * p.theta3 - p.theta2 * p.theta2 * c * c
    a1 = (m22 * b1 - m12 * b2) / det
    a2 = (m11 * b2 - m12 * b1) / det
    a3 = (torques[2] - p.load_mass * p.gravity) / p.vertical_mass
    xdot = ca.vertcat(v1, v2, v3, a1, a2, a3, *current_rates)
    tip_x = p.link1_length * ca.cos(x[0]) + p.link2_length * ca.cos(x[0] + x[1])
    return ca.Function("f", [x, u], [xdot]), ca.Function("tip_x", [x], [tip_x])


def radau_coefficients(degree: int = 3):
    """Collocation points (Radau IIA) and the derivative matrix C: sum_r C[r, j] X_r = h x'(t_j)."""
    import casadi as ca

    tau = np.append(0.0, ca.collocation_points(degree, "radau"))
    C = np.zeros((degree + 1, degree + 1))
    for j in range(degree + 1):
        coefficients = np.poly1d([1.0])
        for r in range(degree + 1):
            if r != j:
                coefficients *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
        derivative = np.polyder(coefficients)
        for r in range(degree + 1):
            C[j, r] = derivative(tau[r])
    return tau, C


@dataclass
class Solution:
    """A solved problem: its time, phase instants, actions (held) and the transcribed path."""

    problem: str
    time: float
    phase_times: tuple[float, float]  # critical from, q3 reaches h_obs
    actions: np.ndarray  # (steps, 3) held actions, or (elements, 3) fractions of the limit (free)
    element_times: np.ndarray  # start instant of every element
    states: np.ndarray  # (elements + 1, 9) state at every element boundary
    phases: np.ndarray  # phase index of every element
    solver_seconds: float
    status: str

    def to_json(self) -> dict:
        return {"problem": self.problem, "time": self.time, "phase_times": list(self.phase_times),
                "actions": self.actions.tolist(), "solver_seconds": self.solver_seconds, "status": self.status}


def _layout(problem: str, config: CollocationConfig, guess_times: tuple[float, float, float]):
    """Elements of the transcription: per element its phase, its control column and a recipe
    for its duration, from the integer structure (held: the steps holding each switch)."""
    dt = config.control_dt
    if problem == "free":
        phases, controls = [], []
        for phase, n in enumerate(config.free_elements):
            phases += [phase] * n
        controls = list(range(len(phases)))
        return np.array(phases), np.array(controls), None
    t_critical, t_above, t_end = guess_times
    k_critical, k_above, k_end = (int(np.floor(t / dt)) for t in (t_critical, t_above, t_end))
    if not k_critical < k_above < k_end:
        raise ValueError(f"phase instants {guess_times} do not fall in distinct control steps")
    phases, controls, parts = [], [], []
    n = config.elements_per_step
    for k in range(k_end + 1):
        if k == k_critical or k == k_above:
            before = 0 if k == k_critical else 1
            for phase, part in ((before, "first"), (before + 1, "second")):
                phases += [phase] * n
                controls += [k] * n
                parts += [(part, "critical" if k == k_critical else "above")] * n
        else:
            phase = 0 if k < k_critical else (1 if k < k_above else 2)
            phases += [phase] * n
            controls += [k] * n
            parts += [("last" if k == k_end else "whole", None)] * n
    return np.array(phases), np.array(controls), (parts, k_critical, k_above, k_end)


def solve(problem: str = "held", start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3),
          params: ScaraParams = DEFAULT_PARAMS, config: CollocationConfig = CollocationConfig(),
          guess: dict | None = None, verbose: bool = False) -> Solution:
    """Minimum time from rest at `start` to the target band (module docstring).

    `guess`: {"times": (critical from, q3 at h_obs, end), "t": sample times, "x": (n, 9)
    states}; by default a run of the environment under the dec heuristic."""
    import casadi as ca

    if problem not in ("held", "free"):
        raise ValueError(f"problem must be 'held' or 'free', got {problem!r}")
    params = params.replace({"task.start": tuple(map(float, start)), "task.target": tuple(map(float, target))})
    p = _values(params)
    guess = guess or heuristic_guess(params)
    f, tip_x = casadi_model(params)
    phases, controls, structure = _layout(problem, config, guess["times"])
    n_el = len(phases)
    degree = 3
    tau, C = radau_coefficients(degree)
    limits = np.array([p.voltage_limit, p.wide_voltage_limit, p.voltage_limit]).T  # (3, phase)

    opti = ca.Opti()
    X = opti.variable(9, n_el + 1)           # state at element boundaries
    XC = opti.variable(9, n_el * degree)     # state at the collocation points
    n_controls = int(controls.max()) + 1
    A = opti.variable(3, n_controls)         # actions: fractions of the voltage limit

    # element durations
    dt = config.control_dt
    if problem == "free":
        T_phase = opti.variable(3)
        opti.subject_to(T_phase >= 1e-3)
        h = ca.vertcat(*[T_phase[ph] / config.free_elements[ph] for ph in phases])
        total_time = ca.sum1(T_phase)
    else:
        parts, k_critical, k_above, k_end = structure
        sigma = opti.variable(3)  # split fractions of the critical and above steps, fraction of the last step
        opti.subject_to(opti.bounded(0.0, sigma, 1.0))
        n = config.elements_per_step
        durations = []
        for part, which in parts:
            if part == "whole":
                durations.append(dt / n)
            elif part == "last":
                durations.append(sigma[2] * dt / n)
            else:
                s = sigma[0] if which == "critical" else sigma[1]
                durations.append((s if part == "first" else 1 - s) * dt / n)
        h = ca.vertcat(*durations)
        total_time = k_end * dt + sigma[2] * dt

    # dynamics: Radau collocation on every element, voltages = action * phase limit
    U = ca.horzcat(*[A[:, controls[e]] * limits[:, phases[e]] for e in range(n_el)])
    F = f.map(n_el * degree)
    rhs = F(XC, U[:, np.repeat(np.arange(n_el), degree).tolist()])
    for j in range(1, degree + 1):
        cols = (np.arange(n_el) * degree + (j - 1)).tolist()
        slope = C[0, j] * X[:, :-1]
        for r in range(1, degree + 1):
            slope += C[r, j] * XC[:, (np.arange(n_el) * degree + (r - 1)).tolist()]
        opti.subject_to(slope == rhs[:, cols] * ca.repmat(h.T, 9, 1))
    opti.subject_to(X[:, 1:] == XC[:, (np.arange(n_el) * degree + degree - 1).tolist()])  # Radau: the last point is the end

    # start, target band, actions, currents
    x0 = np.zeros(9)
    x0[:3] = params.task.start
    opti.subject_to(X[:, 0] == x0)
    band = p.accuracy - config.band_margin
    opti.subject_to(opti.bounded(np.array(target) - band, X[:3, -1], np.array(target) + band))
    opti.subject_to(opti.bounded(-1.0, A, 1.0))
    imax = np.array(p.current_limit)
    all_points = ca.horzcat(X, XC)
    opti.subject_to(opti.bounded(-imax, all_points[6:9, :], imax))

    # phases: the tip's side of the critical band, the wall, q3 against h_obs
    tip = tip_x.map(n_el * degree)(XC)
    point_phase = np.repeat(phases, degree)
    wall, d_crit, height = p.wall_x, p.critical_distance, p.wall_height
    for phase in range(3):
        idx = np.flatnonzero(point_phase == phase).tolist()
        if phase == 0:
            opti.subject_to(tip[idx] >= wall + d_crit)
        elif phase == 1:
            opti.subject_to(opti.bounded(wall + config.wall_margin, tip[idx], wall + d_crit))
            opti.subject_to(XC[2, idx] <= height)
        else:
            opti.subject_to(XC[2, idx] >= height)
    first_b, first_c = int(np.argmax(phases == 1)), int(np.argmax(phases == 2))
    opti.subject_to(tip_x(X[:, first_b]) == wall + d_crit)
    opti.subject_to(X[2, first_c] == height)

    # initial guess: the guess trajectory at the element boundaries, phase instants from it
    t_guess, x_guess = np.asarray(guess["t"]), np.asarray(guess["x"])
    t_c, t_h, t_f = guess["times"]
    if problem == "free":
        T0 = np.array([t_c, t_h - t_c, t_f - t_h])
        opti.set_initial(T_phase, T0)
        starts = np.concatenate([[0.0], np.cumsum(T0)])
        el_t = np.concatenate([starts[ph] + T0[ph] * np.arange(config.free_elements[ph]) / config.free_elements[ph]
                               for ph in range(3)])
    else:
        s0 = [t_c / dt - k_critical, t_h / dt - k_above, t_f / dt - k_end]
        opti.set_initial(sigma, np.clip(s0, 0.05, 0.95))
        guess_durations = np.array(ca.Function("durations", [sigma], [h])(np.clip(s0, 0.05, 0.95))).ravel()
        el_t = np.concatenate([[0.0], np.cumsum(guess_durations)])[:-1]
    el_end = np.append(el_t, t_f)
    X_guess = np.array([np.interp(el_end, t_guess, x_guess[:, i]) for i in range(9)])
    opti.set_initial(X, X_guess)
    colloc_t = (el_t[:, None] + (el_end[1:] - el_t)[:, None] * tau[None, 1:]).ravel()
    opti.set_initial(XC, np.array([np.interp(colloc_t, t_guess, x_guess[:, i]) for i in range(9)]))
    if "a" in guess:
        a_guess = np.asarray(guess["a"])
        at = el_t if problem == "free" else np.arange(n_controls) * dt
        t_actions = guess.get("t_a", guess["t"][:len(a_guess)])
        opti.set_initial(A, np.array([np.interp(at, t_actions, a_guess[:, i]) for i in range(3)]))

    opti.minimize(total_time)
    opti.solver("ipopt", {"expand": True, "print_time": False},
                {"tol": config.ipopt_tol, "max_iter": config.max_iter, "print_level": 5 if verbose else 0,
                 "sb": "yes", "mu_strategy": "adaptive", "linear_solver": "mumps"})
    started = time.perf_counter()
    try:
        sol = opti.solve()
        status = "solved"
    except RuntimeError as error:  # return what IPOPT reached, marked as unsolved
        sol, status = opti.debug, f"not solved: {error}"
    seconds = time.perf_counter() - started
    value = sol.value
    X_val, A_val, h_val = np.array(value(X)), np.array(value(A)), np.array(value(h)).ravel()
    times = np.concatenate([[0.0], np.cumsum(h_val)])
    return Solution(problem=problem, time=float(value(total_time)),
                    phase_times=(float(times[first_b]), float(times[first_c])),
                    actions=A_val.T, element_times=times[:-1], states=X_val.T, phases=phases,
                    solver_seconds=seconds, status=status)


def heuristic_guess(params: ScaraParams, distances=(0.06, 0.08, 0.1, 0.15, 0.2, 0.3)) -> dict:
    """States, actions and phase instants of the dec heuristic (voltage mode) from the start
    to the target: a collision-free path through the same three phases (the first trigger
    distance in `distances` that clears the wall)."""
    import gymnasium as gym

    from agents.policies import DecHeuristic

    env = gym.make("Scara-C11-v1", control_mode="voltage", params=params, start=params.task.start,
                   target=params.task.target).unwrapped
    for distance in distances:
        policy = DecHeuristic(env, "continue", critical_distance=distance)
        obs, _ = env.reset(seed=0)
        ts, xs, acts = [0.0], [np.concatenate([obs[Q], obs[RATES], obs[CURRENTS]])], []
        t_critical = t_above = None
        while True:
            action = policy(obs)
            obs, _, terminated, truncated, info = env.step(action)
            acts.append(action)
            ts.append(info["time"])
            xs.append(np.concatenate([obs[Q], obs[RATES], obs[CURRENTS]]))
            tip_x = obs[OBSERVATION_LAYOUT["tip_x"]]
            if t_critical is None and tip_x < params.obstacle.x_position + params.obstacle.critical_distance:
                t_critical = info["time"] - 0.5 * env.control_dt
            if t_above is None and obs[Q][2] >= params.obstacle.height:
                t_above = info["time"] - 0.5 * env.control_dt
            if terminated or truncated:
                break
        if info["is_success"] and info["collisions"] == 0 and t_critical is not None and t_above is not None:
            return {"times": (t_critical, t_above, info["reach_time"]), "t": np.array(ts), "x": np.array(xs),
                    "a": np.array(acts)}
    raise RuntimeError(f"the dec heuristic does not pass the wall to the target from this start with any "
                       f"trigger distance in {distances} m, so there is no guess for the collocation")


def solution_guess(solution: Solution, control_dt: float) -> dict:
    """A solution as the guess of another solve (its path, actions and phase instants)."""
    return {"times": (*solution.phase_times, solution.time), "t": np.append(solution.element_times, solution.time),
            "x": solution.states, "a": solution.actions,
            "t_a": (solution.element_times if solution.problem == "free"
                    else np.arange(len(solution.actions)) * control_dt)}


def minimum_time(problem: str = "held", start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3),
                 params: ScaraParams = DEFAULT_PARAMS, config: CollocationConfig = CollocationConfig(),
                 rounds: int = 8, verbose: bool = False) -> Solution:
    """The free problem from the heuristic's path; for "held", then the held problem from
    the free solution, solved again until the phase instants and the end fall in the
    control steps its layout assumed (each round starts from the previous solution)."""
    free = solve("free", start, target, params, config, verbose=verbose)
    if problem == "free":
        return free
    solution = solve("held", start, target, params, config, guess=solution_guess(free, config.control_dt),
                     verbose=verbose)
    def layout(solution):
        return [int(np.floor(t / config.control_dt)) for t in (*solution.phase_times, solution.time)]

    for _ in range(rounds):
        if verbose:
            print(f"held: {solution.time:.6f} s, phases {solution.phase_times}, steps {layout(solution)}")
        again = solve("held", start, target, params, config, guess=solution_guess(solution, config.control_dt),
                      verbose=verbose)
        if layout(again) == layout(solution) and abs(again.time - solution.time) < 1e-6:
            return again
        solution = again
    return solution


def cached_solution(start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3), params: ScaraParams = DEFAULT_PARAMS,
                    wall_margin: float = CollocationConfig.wall_margin) -> dict | None:
    """The shipped held solution for this start, target, parameter set and wall margin, if there is one."""
    for path in sorted(SOLUTIONS.glob("*.json")):
        data = json.loads(path.read_text())
        if (np.allclose(data["start"], start, atol=1e-12) and np.allclose(data["target"], target, atol=1e-12)
                and data["params"] == _params_key(params) and data["config"]["wall_margin"] == wall_margin):
            return data
    return None


def _params_key(params: ScaraParams) -> dict:
    record = params.to_record()
    return {name: np.asarray(record[name]).tolist() for name in record.dtype.names
            if name not in ("target", "dec")}


class OptimalPolicy:
    """Replays the held minimum-time actions in a "voltage"-mode environment.

    The actions of the shipped solution (C11 start and target, default parameters) are
    package data; for another start, target or parameter set, ``minimum_time`` solves the
    problem (CasADi needed) when the episode starts. Steps beyond the planned ones (which a
    faithful replay never reaches) command the C11 PD law towards the target."""

    name = "optimal"

    def __init__(self, env, solve_missing: bool = True) -> None:
        self.env = env.unwrapped if hasattr(env, "unwrapped") else env
        if self.env.control_mode != "voltage":
            raise ValueError("the optimal reference commands voltages: it needs control_mode='voltage', "
                             f"the environment is in {self.env.control_mode!r} mode")
        self.solve_missing = solve_missing
        self.plans: dict[tuple, np.ndarray] = {}
        self.actions = None
        self.step_index = 0

    def reset(self) -> None:
        self.actions = None
        self.step_index = 0

    @staticmethod
    def plan_key(start, target) -> tuple:
        """The key of ``plans`` for an episode from start to target."""
        return tuple(np.round(np.concatenate([start, target]), 12))

    def plan(self, start, target) -> np.ndarray:
        key = self.plan_key(start, target)
        if key not in self.plans:
            params = self.env.params
            data = cached_solution(start, target, params)
            if data is not None:
                self.plans[key] = np.array(data["held"]["actions"])
            elif self.solve_missing:
                self.plans[key] = minimum_time("held", start, target, params).actions
            else:
                raise LookupError(f"no shipped minimum-time solution from {list(start)} to {list(target)}")
        return self.plans[key]

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=float)
        target = obs[Q] + obs[OBSERVATION_LAYOUT["target_error"]]
        if self.actions is None:  # the first observation of the episode: the start
            self.actions = self.plan(obs[Q].astype(float).round(6), target.round(6))
        k = self.step_index
        self.step_index += 1
        if k < len(self.actions):
            return np.clip(self.actions[k], -1.0, 1.0)
        return self.env.pd_action(obs, target)


def replaying(actions: np.ndarray, env_id: str, start, target, params: ScaraParams):
    """A "voltage"-mode environment from start to target and an OptimalPolicy in it that
    replays ``actions``."""
    import gymnasium as gym

    env = gym.make(env_id, control_mode="voltage", params=params, start=tuple(start), target=tuple(target))
    policy = OptimalPolicy(env)
    policy.plans[OptimalPolicy.plan_key(start, target)] = np.asarray(actions)
    return env, policy


def replay(actions: np.ndarray, env_id: str = "Scara-C11-v1", start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3),
           params: ScaraParams = DEFAULT_PARAMS) -> dict:
    """Held actions run in the environment ("voltage" mode); the episode summary of
    agents.policies.run_episode (success, collisions, reach_time, energy, ...)."""
    from agents.policies import run_episode

    return run_episode(*replaying(actions, env_id, start, target, params), seed=0)


def _reference_replay(env_id: str, start, target, params: ScaraParams, wall_margin: float):
    """The shipped solution with this wall margin replayed in the environment ("voltage" mode):
    (the observation before each control step, the held action taken there, the task's
    snapshot after each step but the last). Raises if there is no such solution or the replay
    does not reach the target without a collision."""
    data = cached_solution(start, target, params, wall_margin)
    if data is None:
        raise LookupError(f"no shipped minimum-time solution from {list(start)} to {list(target)} with wall margin "
                          f"{wall_margin} m (python -m agents.optimal --wall-margin M --write FILE makes one)")
    env, policy = replaying(np.array(data["held"]["actions"]), env_id, start, target, params)
    task = env.unwrapped.task
    obs, _ = env.reset(seed=0)
    policy.reset()
    observations, actions, snapshots = [], [], []
    while True:
        action = policy(obs)
        observations.append(np.asarray(obs, dtype=np.float64))
        actions.append(np.asarray(action, dtype=np.float64))
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
        snapshots.append(task.snapshot(0))
    env.close()
    if not info["is_success"] or info["collisions"]:
        raise RuntimeError(f"the optimal reference from {list(start)} to {list(target)} does not reach the "
                           f"target without a collision in {env_id}")
    return observations, actions, snapshots


def reference_snapshots(env_id: str = "Scara-C11-v1", start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3),
                        params: ScaraParams = DEFAULT_PARAMS,
                        wall_margin: float = CollocationConfig.wall_margin) -> list[dict]:
    """The states the optimal reference (its shipped solution with this wall margin) passes
    through in the environment, one after each of its control steps before the last (the one
    that reaches the target), as ``ScaraTask.snapshot`` gives them: starts for reference state
    initialization (agents.torch_ppo's ``demo_resets``). Raises if the replay does not reach
    the target."""
    return _reference_replay(env_id, start, target, params, wall_margin)[2]


def reference_demonstration(env_id: str = "Scara-C11-v1", start=(0.0, 0.0, 0.0), target=(2.0, 2.0, 0.3),
                            params: ScaraParams = DEFAULT_PARAMS,
                            wall_margin: float = CollocationConfig.wall_margin) -> tuple[np.ndarray, np.ndarray]:
    """(observations, actions) of the optimal reference's replay in the environment ("voltage"
    mode): the observation before each of its control steps and the held action it takes
    there, as float64 arrays (steps, 18) and (steps, 3). Demonstrations for behaviour cloning
    (agents.torch_ppo's ``demo_bc``). Raises if the replay does not reach the target."""
    observations, actions, _ = _reference_replay(env_id, start, target, params, wall_margin)
    return np.array(observations), np.array(actions)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m agents.optimal", description=__doc__.split("\n\n")[0])
    parser.add_argument("--start", nargs=3, type=float, default=list(DEFAULT_PARAMS.task.start))
    parser.add_argument("--target", nargs=3, type=float, default=list(DEFAULT_PARAMS.task.target))
    parser.add_argument("--write", type=Path, default=None,
                        help="write the solutions as JSON here (the shipped file: agents/optimal_solutions/c11.json)")
    parser.add_argument("--condition", default="c11",
                        help="a parameter shift of agents.compare.CONDITIONS (load-x2, wall-closer, "
                             "current-limits-15, resistance+20); default c11, the C11 parameters")
    parser.add_argument("--wall-margin", type=float, default=CollocationConfig.wall_margin,
                        help="m, distance the held solution keeps from the wall plane while below h_obs (default "
                             "%(default)s; a wider one gives agents.torch_ppo's demo resets states with slack)")
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args(argv)
    from agents.compare import CONDITIONS

    shifts = [name for name, c in CONDITIONS.items() if not c.randomize_target]
    if args.condition not in shifts:
        parser.error(f"--condition must be one of {shifts}, got {args.condition!r}")
    params = DEFAULT_PARAMS.replace(CONDITIONS[args.condition].params)
    if not 0.0 <= args.wall_margin < params.obstacle.critical_distance:
        parser.error(f"--wall-margin must be in [0, {params.obstacle.critical_distance}) m (the critical band), "
                     f"got {args.wall_margin}")
    config = CollocationConfig(wall_margin=args.wall_margin)
    bound_config = CollocationConfig(wall_margin=0.0, band_margin=0.0)
    started = time.perf_counter()
    free = minimum_time("free", args.start, args.target, params, config=bound_config, verbose=args.verbose)
    print(f"free (the continuous-time bound, no margins): {free.time:.5f} s ({free.status}); critical from "
          f"{free.phase_times[0]:.4f} s, q3 at h_obs {free.phase_times[1]:.4f} s")
    held = minimum_time("held", args.start, args.target, params, config=config, verbose=args.verbose)
    result = replay(held.actions, start=args.start, target=args.target, params=params)
    print(f"held (0.01 s steps, margins {config.wall_margin} m / {config.band_margin}): {held.time:.5f} s in the "
          f"transcription ({held.status}); replayed in Scara-C11-v1: success {result['success']}, collisions "
          f"{result['collisions']}, time {result['reach_time']:.5f} s, energy {result['energy']:.1f} J")
    data = {"start": list(args.start), "target": list(args.target), "condition": args.condition,
            "overrides": CONDITIONS[args.condition].params, "params": _params_key(params),
            "config": asdict(config), "free": {**free.to_json(), "config": asdict(bound_config)}, "held": held.to_json(),
            "replay": {k: result[k] for k in ("success", "collisions", "reach_time", "energy", "steps")},
            "seconds": time.perf_counter() - started,
            "command": "python -m agents.optimal" + (f" --start {' '.join(map(str, args.start))}"
                                                     f" --target {' '.join(map(str, args.target))}"
                                                     f" --condition {args.condition}")
                       + (f" --wall-margin {args.wall_margin}" if args.wall_margin != CollocationConfig.wall_margin
                          else "")}
    if args.write:
        args.write.parent.mkdir(parents=True, exist_ok=True)
        args.write.write_text(json.dumps(data, indent=1))
    return data


if __name__ == "__main__":
    main()
