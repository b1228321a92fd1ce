"""Minimum-time reference: the fastest voltages the physics allows, by direct collocation.

    scara-agents optimal                        # C11 target: both problems, replayed in the env
    scara-agents optimal --target 1.5 2.5 0.25

Two problems on the same model and the same transcription (CasADi, Radau collocation of
degree 3, IPOPT):

- ``"held"``: the environment's action interface in ``control_mode="voltage"``: the action
  a_k in [-1, 1]^3 is held over each 0.01 s control step and the voltage is a_k * limit,
  with limit = Umax, widened to Umax_wide from the located instant the tip becomes critical
  until q3 reaches h_obs. Its solution is an action sequence; `OptimalPolicy`
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

import time
from dataclasses import dataclass
from types import SimpleNamespace

import gymnasium as gym
import numpy as np

from agents.policies.heuristic import DecHeuristic
from scara_gym import DEFAULT_PARAMS, ScaraParams
from scara_gym.benchmark.protocol import ENV_ID
from scara_gym.envs import OBSERVATION_LAYOUT
from scara_gym.model.symbolic import symbolic_model

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


def param_values(params: ScaraParams) -> SimpleNamespace:
    """The PARAMS record's fields as attributes (floats and arrays)."""
    record = params.to_record()
    return SimpleNamespace(**{name: (float(record[name]) if np.ndim(record[name]) == 0 else np.array(record[name]))
                              for name in record.dtype.names})


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
    p = param_values(params)
    guess = guess or heuristic_guess(params)
    model = symbolic_model(params, control="voltage")
    f = model.free  # currents free: the constraints below keep them inside their limits

    state = ca.SX.sym("x", 9)
    tip_x = ca.Function("tip_x", [state], [model.tip(state[:3])[0]])
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
    env = gym.make(ENV_ID, control_mode="voltage", params=params, start=params.task.start,
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
