# Lab notebook, not maintained (lab/README.md): written for one entry of docs/experiments.md, on the code of its day.
"""How well posed `scara-c11 accuracy`'s targets are, and what exact switching costs at each tolerance
(the experiments log, 2026-12-04, "the conditioning of the accuracy targets, and the cost of exact
switching at each tolerance").

Prints, in one sitting on this machine:
1. the fastest eigenvalues of the linearized model (the Jacobian of the positions, rates and
   currents) at control-step starts of random "pd" actions;
2. over `scara-c11 accuracy`'s plans (seeds 0-11, 200 episodes each), split into the episodes without
   and with a voltage jump at a critical switch in the "voltage" mode: the worst errors against the
   rtol 1e-10 reference, with the worst episode, of (a) the reference itself started 1e-9 rad (and
   1e-10 rad) away in q1, the problem's own conditioning, and (b) exact switches at rtol 1e-5, 1e-6
   (v1) and 1e-7 (v2), and v0; then v1's episodes over the current target among those without a
   "voltage"-mode jump, with their critical switches and their spread under the 1e-9 rad start;
3. the compiled step's time per control step for the same integrations, best of 5 passes over 1,500
   random actions in each control mode, all in one sitting.

    PYTHONPATH=. python lab/conditioning.py [--seeds 12] [--skip-accuracy] [--skip-timing]

About 15 minutes on 2 cores (the accuracy section about 12).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import scara_gym  # noqa: F401  (registers the ids)
from scara_gym.benchmark.accuracy import TARGETS, run, summary
from scara_gym.benchmark.bench import fastest_compiled_runs
from scara_gym.model.dynamics import derivative
from scara_gym.model.records import CURRENT, N_STATE

ROWS = {  # label -> run() arguments: (rtol, atol, exact_switches, start_offset)
    "reference, start q1 + 1e-9 rad": (1e-10, 1e-12, True, np.array([1e-9, 0.0, 0.0])),
    "reference, start q1 + 1e-10 rad": (1e-10, 1e-12, True, np.array([1e-10, 0.0, 0.0])),
    "exact switches, rtol 1e-5 / atol 1e-7": (1e-5, 1e-7, True, None),
    "exact switches, rtol 1e-6 / atol 1e-8 (v1)": (1e-6, 1e-8, True, None),
    "exact switches, rtol 1e-7 / atol 1e-9 (v2)": (1e-7, 1e-9, True, None),
    "step-end switches, rtol 1e-5 / atol 1e-6 (v0)": (1e-5, 1e-6, False, None),
}
TIMED = {  # label -> constructor arguments over Scara-C11-v2's
    "v0": {"rtol": 1e-5, "atol": 1e-6, "exact_switches": False},
    "exact, rtol 1e-5 / atol 1e-7": {"rtol": 1e-5, "atol": 1e-7},
    "v1": {"rtol": 1e-6, "atol": 1e-8},
    "v2": {},
}


def fastest_modes(cases: int = 40) -> None:
    """Eigenvalues of the Jacobian (forward differences) at control-step starts, set-point applied."""
    env = gym.make("Scara-C11-v2", control_mode="pd")
    task = env.unwrapped._task
    rng = np.random.default_rng(1)
    env.reset(seed=1)
    p, config = task.robot_params[0], task.step_config[0]
    n = CURRENT + 3  # positions, rates and currents (the energy feeds nothing back)
    volts, out, shifted = np.zeros(3), np.empty(N_STATE), np.empty(N_STATE)
    modes = []
    while len(modes) < cases:
        robot = task.robots[0].copy()
        _, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 3))
        if terminated or truncated:
            env.reset()
            continue
        robot["command"] = task.robots[0]["command"]
        x = robot["x"].copy()
        f0 = derivative(x, robot, p, config, np.empty(N_STATE), volts).copy()
        jac = np.empty((n, n))
        for j in range(n):
            shifted[:] = x
            shifted[j] += 1e-7 * max(1.0, abs(x[j]))
            jac[:, j] = (derivative(shifted, robot, p, config, out, volts)[:n] - f0[:n]) / (shifted[j] - x[j])
        eigenvalues = np.linalg.eigvals(jac)
        modes.append(eigenvalues)
    fast = [z for case in modes for z in case if abs(z) > 100.0]  # the electromechanical modes
    oscillating = [z for z in fast if abs(z.imag) > 1.0] or [complex(0.0)]
    slowest = min(oscillating, key=lambda z: -z.real)
    print(f"1. the eigenvalues faster than 100/s of the linearized model at {cases} control-step starts (random "
          f"'pd' actions, seed 1): {len(fast) / cases:.1f} per start, |lambda| {min(map(abs, fast)):.0f}-"
          f"{max(map(abs, fast)):.0f}/s, {len(oscillating) / cases:.1f} of them complex; the least damped "
          f"{slowest.real:.0f}{slowest.imag:+.0f}i/s keeps e^{slowest.real * 0.01:.1f} = "
          f"{np.exp(slowest.real * 0.01):.2f} of its amplitude over a 0.01 s control step")
    print("   at the first start: " + ", ".join(f"{z.real:.0f}{z.imag:+.0f}i" for z in modes[0] if abs(z) > 100.0),
          flush=True)


def worst(rows: list[dict]) -> str:
    """summary()'s worst of each quantity (ratio to its target, episodes over it) with the worst episode
    as seed/index, then its events without a partner and its episodes that ended apart."""
    if not rows:
        return "no episodes"
    result = summary(rows)
    cells = []
    for name, target in TARGETS.items():
        over = len(result["over_target"][name])
        row = max(rows, key=lambda r: r[name])
        cells.append(f"{name} {result[name]:.1e} ({result[name] / target:.2f}{f', {over} over' if over else ''}; "
                     f"{row['seed']}/{row['index']})")
    return "; ".join(cells) + (f"; {result['unpaired_events']} events without a partner, "
                               f"{result['ended_apart']} episodes ended apart")


def accuracy_rows(seeds: int) -> dict:
    print(f"2. worst error against the rtol 1e-10 reference (ratio to the target; episodes over it; the worst "
          f"episode as seed/index), seeds 0-{seeds - 1} x 200 episodes")
    results = {}
    for label, (rtol, atol, exact, offset) in ROWS.items():
        started = time.perf_counter()
        rows = results[label] = [{**row, "seed": seed} for seed in range(seeds)
                                 for row in run(200, seed, rtol, atol, exact, None, offset)]
        jumps = [row for row in rows if row["voltage_jumps"]]
        smooth = [row for row in rows if not row["voltage_jumps"]]
        print(f"   {label} ({summary(rows)['rhs_per_step']:.1f} RHS per control step; "
              f"{time.perf_counter() - started:.0f} s)\n"
              f"      {len(smooth)} episodes without a voltage-mode jump: {worst(smooth)}\n"
              f"      {len(jumps)} with one: {worst(jumps)}", flush=True)
    return results


def pd_jumps(results: dict) -> None:
    """v1's episodes over the current target among those without a voltage-mode jump: are they "pd"
    episodes with critical switches, and how far does the 1e-9 rad start move their currents?"""
    v1 = "exact switches, rtol 1e-6 / atol 1e-8 (v1)"
    spread = {(r["seed"], r["index"]): r for r in results["reference, start q1 + 1e-9 rad"]}
    print(f"   {v1}, over the current target without a voltage-mode jump:")
    for row in results[v1]:
        if row["current"] > TARGETS["current"] and not row["voltage_jumps"]:
            moved = spread[row["seed"], row["index"]]
            print(f"      seed {row['seed']}, episode {row['index']}: {row['control_mode']} mode, obstacle "
                  f"{row['obstacle']}, {row['critical_switches']} critical switches; current {row['current']:.1e} A, "
                  f"event time {row['event_time']:.1e} s, q {row['q']:.1e}; the reference started 1e-9 rad away: "
                  f"current {moved['current']:.1e} A, event time {moved['event_time']:.1e} s", flush=True)


def compiled_times(steps: int = 1500, rounds: int = 5) -> None:
    print(f"3. compiled step [us per control step], best of {rounds} passes over {steps} random actions")
    for control_mode in ("pd", "voltage"):
        envs = {label: gym.make("Scara-C11-v2", control_mode=control_mode, **kwargs) for label, kwargs in TIMED.items()}
        best = fastest_compiled_runs(envs, steps, rounds)
        v0 = best["v0"]["untimed"]
        for label, result in best.items():
            print(f"   {control_mode}, {label}: {result['untimed'] / steps * 1e6:.2f} us ({v0 / result['untimed']:.2f}x "
                  f"v0's speed), {result['rhs'] / steps:.1f} RHS and {result['steps'] / steps:.1f} integration steps "
                  f"per control step", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=12)
    parser.add_argument("--skip-accuracy", action="store_true")
    parser.add_argument("--skip-timing", action="store_true")
    args = parser.parse_args()
    # v0 and v1 are measured on purpose: Gymnasium says once each that they are out of date
    fastest_modes()
    if not args.skip_accuracy:
        pd_jumps(accuracy_rows(args.seeds))
    if not args.skip_timing:
        compiled_times()


if __name__ == "__main__":
    main()
