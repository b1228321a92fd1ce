# Lab notebook, not maintained (lab/README.md): written for one entry of docs/experiments.md, on the code of its day.
"""Where Scara-C11-v2's right-hand sides go, and integrators that might spend fewer (the experiments
log, 2026-12-02). Counts, not times: the figures do not depend on the machine's load.

    python lab/integrators.py

1. Per control step of random "pd" actions: right-hand sides, accepted and rejected steps, by the
   number of mode changes in the step (v0 beside v2).
2. DOPRI5, a Lawson (integrating-factor) DOPRI5, DOP853 and an exponential Rosenbrock method (exprb32)
   on 60 control steps with the robot's mode at the step's start held (a smooth ODE with the same
   transients), against DOP853 at rtol 1e-13.
"""


import gymnasium as gym
import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm

import scara_gym  # noqa: F401  (registers the ids)
from scara_gym.model.dynamics import derivative
from scara_gym.model.integrator import RK_A, RK_B, RK_C, RK_E

CONTROL_DT = 0.01


def counts(env_id: str, steps: int = 1500, seed: int = 1) -> None:
    env = gym.make(env_id, control_mode="pd")
    task = env.unwrapped._task
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    rows = []
    for _ in range(steps):
        before = task.robots[0].copy()
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 3))
        after = task.robots[0]
        if terminated or truncated:
            env.reset()
            continue
        changes = int(np.sum(before["saturation"] != after["saturation"]) + np.sum(before["hold"] != after["hold"]))
        rows.append((after["n_rhs"] - before["n_rhs"], after["n_steps"] - before["n_steps"],
                     after["n_rejected"] - before["n_rejected"], changes))
    rows = np.array(rows)
    rhs, accepted, rejected = rows[:, :3].mean(0)
    print(f"{env_id}: {rhs:.0f} right-hand sides, {accepted:.1f} accepted and {rejected:.1f} rejected steps per control step")
    for n in range(4):
        chosen = rows[:, 3] == n
        if chosen.any():
            print(f"  {chosen.sum():4d} control steps with {n} net mode changes: {rows[chosen, 0].mean():.0f} right-hand sides")


def held_mode_cases(count: int = 60, skip: int = 20, seed: int = 1) -> tuple[list, object, object]:
    """Robot records at control-step starts (their set-point applied), from random pd actions."""
    env = gym.make("Scara-C11-v2", control_mode="pd")
    task = env.unwrapped._task
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    cases = []
    while len(cases) < skip + count:
        before = task.robots[0].copy()
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 3))
        if terminated or truncated:
            env.reset()
            continue
        robot = before.copy()
        robot["command"] = task.robots[0]["command"]
        cases.append(robot)
    return cases[skip:], task.robot_params[0], task.step_config[0]


def rhs(robot, p, config):
    volts = np.zeros(3)

    def f(t, x):
        out = np.empty_like(x)
        derivative(x, robot, p, config, out, volts)
        return out
    return f


C7 = np.append(RK_C, 1.0)
A7 = np.zeros((7, 7))
A7[:RK_A.shape[0], :RK_A.shape[1]] = RK_A
A7[6, :6] = RK_B
B_EMBEDDED = np.append(RK_B, 0.0) - RK_E


def lawson_dopri5(f, lam, x0, t_end, rtol, atol, h=1e-4):
    """DOPRI5 on w = exp(-lam t) x (lam: the diagonal linear part), scipy's error control."""
    t, x, evaluations, accepted = 0.0, x0.copy(), 0, 0
    nonlinear = lambda y: f(0.0, y) - lam * y  # noqa: E731
    while t < t_end:
        h = min(h, t_end - t)
        k = np.zeros((7, x.size))
        for i in range(7):
            stage = np.exp(C7[i] * h * lam) * x
            for j in range(i):
                if A7[i, j]:
                    stage = stage + h * A7[i, j] * np.exp((C7[i] - C7[j]) * h * lam) * k[j]
            k[i] = nonlinear(stage)
            evaluations += 1
        y_new = stage
        y_hat = np.exp(h * lam) * x + h * sum(B_EMBEDDED[j] * np.exp((1 - C7[j]) * h * lam) * k[j] for j in range(7))
        scale = atol + rtol * np.maximum(np.abs(x), np.abs(y_new))
        err = np.sqrt(np.mean(((y_new - y_hat) / scale) ** 2))
        if err <= 1.0:
            t, x, accepted = t + h, y_new, accepted + 1
            h *= min(10.0, 0.9 * err ** -0.2) if err > 0 else 10.0
        else:
            h *= max(0.2, 0.9 * err ** -0.2)
    return x, evaluations, accepted


def phi_times(a: np.ndarray, b: np.ndarray, order: int) -> np.ndarray:
    """phi_order(a) b, from the exponential of a augmented by b and a shift (Sidje's Expokit)."""
    n = a.shape[0]
    augmented = np.zeros((n + order, n + order))
    augmented[:n, :n] = a
    augmented[:n, n] = b
    for i in range(order - 1):
        augmented[n + i, n + i + 1] = 1.0
    return expm(augmented)[:n, n + order - 1]


def jacobian(f, x, fx):
    """Forward differences: the cost an analytic Jacobian would have is not counted in the RHS."""
    columns = []
    for j in range(x.size):
        step = 1e-7 * max(1.0, abs(x[j]))
        shifted = x.copy()
        shifted[j] += step
        columns.append((f(0.0, shifted) - fx) / step)
    return np.array(columns).T


def exprb32(f, x0, t_end, rtol, atol, h=1e-4):
    """The exponential Rosenbrock method of order 3 with its order-2 (exponential Rosenbrock-Euler)
    embedding (Hochbruck, Ostermann and Schweitzer 2009): the Jacobian at each step's start taken
    exactly, the remainder f(x) - J x explicitly; 2 RHS, one Jacobian and two matrix functions a step."""
    t, x = 0.0, x0.copy()
    fx = f(0.0, x)
    evaluations, accepted, jacobians = 1, 0, 0
    while t < t_end - 1e-15:
        h = min(h, t_end - t)
        jac = jacobian(f, x, fx)
        jacobians += 1
        while True:
            u = x + phi_times(h * jac, h * fx, 1)
            remainder = f(0.0, u) - fx - jac @ (u - x)
            evaluations += 1
            correction = 2.0 * phi_times(h * jac, h * remainder, 3)
            y_new = u + correction
            scale = atol + rtol * np.maximum(np.abs(x), np.abs(y_new))
            err = np.sqrt(np.mean((correction / scale) ** 2))
            if err <= 1.0:
                break
            h *= max(0.2, 0.9 * err ** (-1 / 3))
        t, x, accepted = t + h, y_new, accepted + 1
        fx = f(0.0, x)
        evaluations += 1
        h *= min(10.0, 0.9 * err ** (-1 / 3)) if err > 0 else 10.0
    return x, evaluations, accepted, jacobians


def compare_integrators() -> None:
    cases, p, config = held_mode_cases()
    decay = -np.asarray(p["resistance"], float) / np.asarray(p["inductance"], float)
    references = [solve_ivp(rhs(r, p, config), (0, CONTROL_DT), r["x"].copy(), method="DOP853", rtol=1e-13,
                            atol=1e-15).y[:, -1] for r in cases]

    def report(label, results):
        errors = np.max([np.abs(x - ref) for (x, _, _), ref in zip(results, references)], axis=0)
        print(f"| {label} | {np.mean([r[1] for r in results]):.0f} | {np.mean([r[2] for r in results]):.1f} | "
              f"{errors[:3].max():.1e} | {errors[3:6].max():.1e} | {errors[6:9].max():.1e} |")

    print("| integrator, rtol / atol | RHS per control step | steps | error q | error rates | error currents |")
    print("|---|---|---|---|---|---|")
    for rtol, atol in ((1e-7, 1e-9), (1e-6, 1e-8), (1e-5, 1e-7)):
        for method in ("RK45", "Lawson", "DOP853", "exprb32"):
            results = []
            for r in cases:
                if method == "Lawson":
                    lam = np.zeros(r["x"].size)
                    lam[6:9] = np.where(r["hold"] == 0, decay, 0.0)  # a held current has I' = 0
                    results.append(lawson_dopri5(rhs(r, p, config), lam, r["x"].copy(), CONTROL_DT, rtol, atol))
                elif method == "exprb32":  # plus one Jacobian per step (forward differences, not counted)
                    results.append(exprb32(rhs(r, p, config), r["x"].copy(), CONTROL_DT, rtol, atol)[:3])
                else:
                    sol = solve_ivp(rhs(r, p, config), (0, CONTROL_DT), r["x"].copy(), method=method, rtol=rtol,
                                    atol=atol)
                    results.append((sol.y[:, -1], sol.nfev, sol.t.size - 1))
            report(f"{'DOPRI5' if method == 'RK45' else method} {rtol:g} / {atol:g}", results)


if __name__ == "__main__":
    counts("Scara-C11-v0")
    counts("Scara-C11-v2")
    compare_integrators()
