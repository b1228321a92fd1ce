"""``scara-c11 bench``: speed figures, measured side by side in one run.

1. Task b to its located stop event: the compiled integrator (explicit and implicit
   form) against scipy's ``solve_ivp`` with the same model functions, the same hybrid
   current-limit modes and the same tolerances.
2. One environment through ``gym.make``, random actions, next to Gymnasium's
   Pendulum-v1 and CartPole-v1 (and MuJoCo's Reacher-v5 where mujoco is installed).
   Then where a step's time goes, per id (bench_cost): Python, right-hand sides, switch
   search, event location and bookkeeping, with right-hand sides and integration steps.
3. The native vector environment at N robots next to Gymnasium's vectorized CartPole.
   Then the environment's integration tolerance: speed against accuracy.
4. Peak memory of the largest vector environment, and cold / warm start of
   ``gym.make`` + reset + first step (fresh processes; cold = empty JIT cache).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

from scara_gym.benchmark.reference import scipy_point_to_point
from scara_gym.benchmark.tasks import point_to_point
from scara_gym.extras import require


def _best(run, repeats: int) -> tuple[float, float]:
    """(best runtime [s], reach time [s]) over repeats."""
    times, reach = [], None
    for _ in range(repeats):
        started = time.perf_counter()
        reach = run()
        times.append(time.perf_counter() - started)
    return min(times), reach


def bench_task_b(rtol: float = 1e-6, atol: float = 1e-9, repeats: int = 5,
                 scipy_methods=("RK45", "LSODA")) -> list[dict]:
    point_to_point(rtol=rtol, atol=atol)  # compile / load the cache outside the timing
    point_to_point(form="implicit", rtol=rtol, atol=atol)
    rows = []
    for form in ("explicit", "implicit"):
        best, reach = _best(lambda form=form: point_to_point(form=form, rtol=rtol, atol=atol).reach_time, repeats)
        rows.append({"solver": f"scara_gym compiled DOPRI5, {form}", "runtime": best, "reach": reach})
    for method in scipy_methods:
        best, reach = _best(lambda method=method: scipy_point_to_point(method=method, rtol=rtol, atol=atol)[0],
                            max(1, repeats // 2))
        rows.append({"solver": f"scipy solve_ivp {method}, explicit", "runtime": best, "reach": reach})
    base = rows[0]["runtime"]
    for row in rows:
        row["ratio"] = row["runtime"] / base
    return rows


def format_rows(rows: list[dict], rtol: float, atol: float) -> str:
    lines = [f"Task b to the stop event (rtol {rtol:g}, atol {atol:g}), best of repeats:",
             "| solver | runtime | x our explicit | reach time |", "|---|---|---|---|"]
    for row in rows:
        lines.append(f"| {row['solver']} | {row['runtime'] * 1e3:.3f} ms | {row['ratio']:.1f} "
                     f"| {row['reach']:.6f} s |")
    return "\n".join(lines)


def _steps_per_second(env, steps: int, seed: int = 0) -> float:
    """Random actions (seeded), resetting at episode ends, timed over `steps` steps."""
    env.reset(seed=seed)
    env.action_space.seed(seed)
    actions = [env.action_space.sample() for _ in range(steps)]
    env.step(actions[0])
    started = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - started)


def _interleaved_best(measures: dict, rounds: int) -> dict:
    """Best of `rounds` for each measure, taken in turns: the machine's speed drifts, and
    measures side by side in every round keep the ratios fair.
    """
    best = dict.fromkeys(measures, 0.0)
    for _ in range(rounds):
        for label, measure in measures.items():
            best[label] = max(best[label], measure())
    return best


def bench_single(steps: int, rounds: int = 5) -> list[tuple[str, float]]:

    import gymnasium as gym

    import scara_gym

    candidates = [(f"{env_id}, {mode}", env_id, {"control_mode": mode})
                  for env_id in scara_gym.ENV_VERSIONS for mode in ("pd", "voltage")]
    candidates += [("Pendulum-v1", "Pendulum-v1", {}), ("CartPole-v1", "CartPole-v1", {})]
    try:
        import mujoco  # noqa: F401
        candidates.append(("Reacher-v5 (MuJoCo)", "Reacher-v5", {}))
    except ImportError:
        pass
    envs = {label: gym.make(gym.spec(env_id), **kwargs) for label, env_id, kwargs in candidates}
    per_round = max(1, steps // rounds)
    best = _interleaved_best({label: lambda env=env: _steps_per_second(env, per_round)
                              for label, env in envs.items()}, rounds)
    return list(best.items())


def _vector_steps_per_second(venv, steps: int) -> float:
    venv.reset(seed=0)
    venv.action_space.seed(0)
    actions = [venv.action_space.sample() for _ in range(steps + 1)]
    venv.step(actions[0])
    started = time.perf_counter()
    for action in actions[1:]:
        venv.step(action)
    return steps * venv.num_envs / (time.perf_counter() - started)


def bench_vector(sizes, steps: int, modes=("voltage", "pd"), env_ids=None) -> list[tuple[str, str, int, float, float]]:
    """(env id, control mode, N, robot-steps/s, CartPole-v1's steps/s) per size, mode and id."""
    import gymnasium as gym

    import scara_gym

    rows = []
    for n in sizes:
        cartpole = _vector_steps_per_second(
            gym.make_vec("CartPole-v1", num_envs=n, vectorization_mode="vector_entry_point"), steps)
        for env_id in env_ids or scara_gym.ENV_VERSIONS:
            for mode in modes:
                venv = gym.make_vec(gym.spec(env_id), num_envs=n, vectorization_mode="vector_entry_point",
                                    control_mode=mode, collision="penalty")
                rows.append((env_id, mode, n, _vector_steps_per_second(venv, steps), cartpole))
    return rows


def _seconds_per_cycle() -> float:
    """The cycle counter's period, against the clock (0 where the CPU has no readable counter)."""
    from scara_gym.envs.core import cycle_counter

    cycle_counter()
    first, started = cycle_counter(), time.perf_counter()
    time.sleep(0.2)
    last, elapsed = cycle_counter(), time.perf_counter() - started
    return elapsed / (last - first) if last > first else 0.0


COST_PARTS = ("python", "rhs", "search", "locate", "bookkeeping")
"""The parts of bench_cost's breakdown (its rows' keys, in microseconds per step)."""


def bench_cost(env_ids=None, steps: int = 1000, control_mode: str = "pd", rounds: int = 3) -> list[dict]:
    """Where the time of one environment step goes, per id: one env via gym.make, seeded random
    actions. The step's wall time (best of `rounds`, ids in turns) splits into the Python
    around the compiled step (gym.make's step less one timed call of the compiled step), the
    right-hand sides (their count times the cost of one, timed on the episode's states), the
    switch search (event values at each integration step's end and the search inside it) and
    the event location (root refinement, mode switches, restart), both from the cycle counter
    of a separately compiled timed step, and the bookkeeping: the rest of the compiled step
    (Runge-Kutta stages' arithmetic, error control, reward and observation). Rows: id,
    steps_per_second, total and COST_PARTS [us per step], rhs_per_step, steps_per_step
    (integration steps, rejected ones included).
    """
    import gymnasium as gym

    import scara_gym
    from scara_gym.envs.core import T_STEP
    from scara_gym.model.integrator import T_LOCATE, T_SEARCH, rhs_cycles

    env_ids = tuple(env_ids or scara_gym.ENV_VERSIONS)
    envs = {env_id: gym.make(gym.spec(env_id), control_mode=control_mode) for env_id in env_ids}
    rates = _interleaved_best({env_id: lambda env=env: _steps_per_second(env, steps)
                               for env_id, env in envs.items()}, rounds)
    seconds_per_cycle = _seconds_per_cycle()
    runs = {env_id: _compiled_run(env, steps) for env_id, env in envs.items()}  # compiles, and the states
    for _ in range(rounds - 1):  # best of rounds, ids in turns, as for the rates
        for env_id, env in envs.items():
            run = _compiled_run(env, steps)
            best = runs[env_id]
            best["untimed"] = min(best["untimed"], run["untimed"])
            if run["timers"][T_STEP] < best["timers"][T_STEP]:
                best["timers"] = run["timers"]
    rows = []
    for env_id, env in envs.items():
        task = env.unwrapped._task
        run = runs[env_id]
        timers, rhs, integration_steps, untimed = run["timers"], run["rhs"], run["steps"], run["untimed"]
        robot = task.robots[0]
        rhs_seconds = seconds_per_cycle * min(
            rhs_cycles(run["states"], robot, task.robot_params[0], task.step_config[0], 50)[0] for _ in range(rounds))
        us = 1e6 / steps
        total = 1e6 / rates[env_id]
        compiled = untimed * us
        row = {"env_id": env_id, "steps_per_second": rates[env_id], "total": total, "python": total - compiled,
               "rhs": rhs * rhs_seconds * us, "search": timers[T_SEARCH] * seconds_per_cycle * us,
               "locate": timers[T_LOCATE] * seconds_per_cycle * us,
               "rhs_per_step": rhs / steps, "steps_per_step": integration_steps / steps,
               "timed_step": timers[T_STEP] * seconds_per_cycle * us}
        row["bookkeeping"] = compiled - row["rhs"] - row["search"] - row["locate"]
        rows.append(row)
    return rows


def _compiled_run(env, steps: int) -> dict:
    """bench_cost's compiled passes over one env's seeded actions: the compiled step timed from
    Python (untimed, [s]), then the timed step (its timers [cycles], right-hand sides, integration
    steps and up to 512 of the visited states).
    """
    import numpy as np

    from scara_gym.envs.core import N_TIMERS, profile_robot, step_robot

    task = env.unwrapped._task
    arrays = (task.robots, task.robot_params, task.step_config, task.constants, task.log, task.outcomes, task.obs)
    robot, outcome = task.robots[0], task.outcomes[0]
    env.action_space.seed(0)
    actions = [np.asarray(env.action_space.sample(), dtype=np.float64) for _ in range(steps)]
    run = {"timers": np.zeros(N_TIMERS, dtype=np.int64), "untimed": 0.0, "rhs": 0, "steps": 0, "states": []}
    for timed in (False, True):
        env.reset(seed=0)
        for action in actions:
            if timed:
                before = robot["n_rhs"], robot["n_steps"] + robot["n_rejected"]
                status = profile_robot(0, action, *arrays, run["timers"])
                run["rhs"] += int(robot["n_rhs"] - before[0])
                run["steps"] += int(robot["n_steps"] + robot["n_rejected"] - before[1])
                if len(run["states"]) < 512:
                    run["states"].append(robot["x"].copy())
            else:
                started = time.perf_counter()
                status = step_robot(0, action, *arrays)
                run["untimed"] += time.perf_counter() - started
            if status < 0:
                raise RuntimeError(f"{env.spec.id}: integrator status {status}")
            collided = outcome["collisions"] > 0 and task.collision_mode == "terminate"
            if outcome["reached"] or collided or outcome["episode_steps"] >= env.spec.max_episode_steps:
                env.reset()
    run["states"] = np.array(run["states"])
    return run


def fastest_compiled_runs(envs: dict, steps: int, rounds: int) -> dict:
    """_compiled_run over each env (label -> env), the envs in turns for `rounds` rounds: per label the
    run of the fastest untimed pass (the counts are the same in every pass).
    """
    best = {}
    for _ in range(rounds):
        for label, env in envs.items():
            run = _compiled_run(env, steps)
            if label not in best or run["untimed"] < best[label]["untimed"]:
                best[label] = run
    return best


def format_cost(rows: list[dict], control_mode: str = "pd") -> str:
    lines = [f"Where a step's time goes, one env via gym.make ({control_mode} mode, random actions), us per step:",
             "| env id | steps/s | total | Python | right-hand sides | switch search | event location | "
             "bookkeeping | RHS per step | integration steps per step |", "|---|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {row['env_id']} | {row['steps_per_second']:,.0f} | {row['total']:.1f} | {row['python']:.1f} | "
              f"{row['rhs']:.1f} | {row['search']:.1f} | {row['locate']:.1f} | {row['bookkeeping']:.1f} | "
              f"{row['rhs_per_step']:.1f} | {row['steps_per_step']:.1f} |" for row in rows]
    lines.append("(Search and location from the cycle counter of a separately compiled timed step, whose timer "
                 "reads they include; bookkeeping is the rest of the compiled step: stages' arithmetic, error "
                 "control, reward, observation.)")
    return "\n".join(lines)


TOLERANCES = ((1e-5, 1e-6), (1e-4, 1e-5), (1e-3, 1e-4))
TIGHT = (1e-10, 1e-12)


def bench_tolerance(steps: int, tolerances=TOLERANCES) -> list[dict]:
    """Speed against accuracy of the environment's integration tolerances.

    One random-action voltage-mode episode (the bench's load), stepped at each (rtol,
    atol) and at tight tolerances; the error is the largest deviation of the joint
    positions after a control step from the tight run.
    """
    import numpy as np

    from scara_gym.envs.scara_env import ScaraEnv

    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.0, 1.0, (steps, 3)).astype(np.float32)

    def run(rtol, atol):
        env = ScaraEnv(control_mode="voltage", collision="penalty", rtol=rtol, atol=atol)
        env.reset(seed=0)
        positions = []
        started = time.perf_counter()
        for action in actions:
            terminated = env.step(action)[2]
            positions.append(env.state[:3])
            if terminated:  # reached the target by chance: compare the common part
                break
        elapsed = time.perf_counter() - started
        return np.array(positions), len(positions) / elapsed, env._task.robots["n_rhs"][0] / len(positions)

    reference, _, _ = run(*TIGHT)  # also loads the compiled code before any timed run
    runs = {tol: run(*tol) for tol in tolerances}
    rates = _interleaved_best({tol: lambda tol=tol: run(*tol)[1] for tol in tolerances}, 3)
    rows = []
    for (rtol, atol), (positions, _, rhs) in runs.items():
        common = min(len(positions), len(reference))
        rows.append({"rtol": rtol, "atol": atol, "rate": rates[(rtol, atol)], "rhs": rhs,
                     "error": float(np.max(np.abs(positions[:common] - reference[:common])))})
    return rows


_START_SCRIPT = """
import time
started = time.perf_counter()
import gymnasium as gym
import scara_gym
env = gym.make("Scara-C11-v0")
env.reset(seed=0)
env.step(env.action_space.sample())
print(time.perf_counter() - started)
"""

_MEMORY_SCRIPT = """
import resource, sys, tracemalloc
import numpy as np
import gymnasium as gym
import scara_gym
warm = gym.make_vec("Scara-C11-v0", num_envs=2, vectorization_mode="vector_entry_point")
warm.reset(seed=0)
warm.step(warm.action_space.sample())  # load the compiled code first: not the env's memory
tracemalloc.start()
venv = gym.make_vec("Scara-C11-v0", num_envs=int(sys.argv[1]), vectorization_mode="vector_entry_point")
venv.reset(seed=0)
for _ in range(20):
    venv.step(venv.action_space.sample())
_, peak = tracemalloc.get_traced_memory()
print(peak, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
"""


def _run_python(script: str, *args: str, env: dict | None = None) -> str:
    out = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True,
                         env={**os.environ, **(env or {})}, check=True)
    return out.stdout.strip()


def bench_start() -> tuple[float, float]:
    """(cold, warm) seconds for import + gym.make + reset + first step in a fresh process."""
    with tempfile.TemporaryDirectory() as cache:
        cold = float(_run_python(_START_SCRIPT, env={"NUMBA_CACHE_DIR": cache}))
        warm = float(_run_python(_START_SCRIPT, env={"NUMBA_CACHE_DIR": cache}))
    return cold, warm


def bench_memory(n: int) -> tuple[float, float]:
    """(peak memory allocated by the vector env and 20 steps, peak RSS of the process) in MiB."""
    env_peak, process_peak = (int(v) for v in _run_python(_MEMORY_SCRIPT, str(n)).split())
    return env_peak / 2**20, process_peak / 2**20


GPU_SIZES = (4096, 65536, 262144, 1048576)


def gpu_available() -> str | None:
    """None when a CUDA GPU can run the CUDA backend, else why not (in words)."""
    try:
        from scara_gym.envs.cuda_vector import load_backend

        load_backend()
    except (ImportError, RuntimeError) as error:
        return str(error)
    import numba
    if numba.config.ENABLE_CUDASIM:
        return "NUMBA_ENABLE_CUDASIM=1: the simulator is not timed"
    return None


def bench_gpu(sizes=GPU_SIZES, steps: int = 50, env_id: str = "Scara-C11-v1") -> list[dict]:
    """Robot-steps/s of the CUDA vector env (random voltage actions drawn on the GPU) per N, and
    the largest |q| difference to the CPU vector env after `steps` steps of the same actions
    (on the first 256 robots).
    """
    import gymnasium as gym
    import numpy as np
    require("torch")
    import torch

    rows = []
    for n in sizes:
        gpu = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", device="cuda",
                           control_mode="voltage", collision="penalty")
        device = gpu.unwrapped.device  # the CPU on numba's simulator (where the code is tested)
        synchronize = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)
        generator = torch.Generator(device=device).manual_seed(0)
        gpu.reset(seed=0)
        actions = [torch.rand((n, 3), generator=generator, device=device, dtype=torch.float64) * 2 - 1
                   for _ in range(steps)]
        gpu.step(actions[0])  # compiles the kernels
        gpu.reset(seed=0)
        synchronize()
        started = time.perf_counter()
        for action in actions:
            gpu.step(action)
        synchronize()
        rate = n * steps / (time.perf_counter() - started)
        compared = min(n, 256)
        cpu = gym.make_vec(env_id, num_envs=compared, vectorization_mode="vector_entry_point",
                           control_mode="voltage", collision="penalty")
        cpu.reset(seed=0)
        for action in actions:
            cpu.step(action[:compared].cpu().numpy())
        q_gpu = gpu.unwrapped.d_robots.copy_to_host()["x"][:compared, :3]
        q_cpu = cpu.unwrapped._task.robots["x"][:, :3]
        rows.append({"n": n, "rate": rate, "q_difference": float(np.abs(q_gpu - q_cpu).max())})
        gpu.close(), cpu.close()
    return rows


def bench_warp_bound(control_mode: str = "voltage", n: int = 4096, steps: int = 60, warp: int = 32,
                     env_id: str = "Scara-C11-v1", seed: int = 0) -> dict:
    """The loop-count divergence of a one-thread-per-robot GPU step, from the CPU env: per
    control step, each robot's right-hand-side evaluations (its integrator work); robots i..i+31
    share a warp, which runs as long as its busiest robot. Returns the work-weighted SIMT
    efficiency sum(work) / sum(warp * max work in the warp) over random actions (the first 5
    steps left out), the same with warps formed by sorting the robots on their previous step's
    work, and the mean and largest work per step. Branches inside an integrator step (event
    search, mode switches) diverge further; a GPU profile sees those, this does not.
    """
    import gymnasium as gym
    import numpy as np

    import scara_gym  # noqa: F401

    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", control_mode=control_mode)
    venv.reset(seed=seed)
    counts = venv.unwrapped._task.robots["n_rhs"]  # per episode: a reset robot starts again from 0
    rng = np.random.default_rng(seed)
    previous, last_work, rows = counts.copy(), None, []
    for step in range(steps):
        venv.step(rng.uniform(-1.0, 1.0, (n, 3)))
        now = counts.copy()
        work = np.where(now >= previous, now - previous, now)
        grouped = work.reshape(-1, warp)
        sorted_work = work[np.argsort(last_work, kind="stable")].reshape(-1, warp) if last_work is not None else None
        if step >= 5:
            rows.append((grouped.sum() / (warp * grouped.max(1)).sum(),
                         sorted_work.sum() / (warp * sorted_work.max(1)).sum(), work.mean(), work.max()))
        previous, last_work = now, work
    venv.close()
    efficiency, sorted_efficiency, mean, largest = np.array(rows).T
    return {"efficiency": float(efficiency.mean()), "sorted_efficiency": float(sorted_efficiency.mean()),
            "mean_work": float(mean.mean()), "largest_work": int(largest.max())}


def main(quick: bool = False, stream=None, gpu_only: bool = False) -> str:
    """The bench's report (printed to ``stream`` as it is measured). The older ids are measured on
    purpose beside the latest: the bench builds them from their specs (``gym.make(gym.spec(id))``),
    which Gymnasium does not call out of date.
    """
    stream = sys.stdout if stream is None else stream  # at call time: a stream bound at import can be stale
    if gpu_only:
        return gpu_section(quick, stream)
    repeats = 2 if quick else 7
    chunks = []
    for rtol, atol in ((1e-6, 1e-9),) if quick else ((1e-6, 1e-9), (1e-10, 1e-12)):
        rows = bench_task_b(rtol, atol, repeats)
        chunks.append(format_rows(rows, rtol, atol))
        print(chunks[-1] + "\n", file=stream, flush=True)

    single = bench_single(200 if quick else 5000)
    base = dict(single)["Pendulum-v1"]
    lines = ["One environment via gym.make, random actions:", "| environment | steps/s | x Pendulum-v1 |",
             "|---|---|---|"]
    lines += [f"| {label} | {rate:,.0f} | {rate / base:.2f} |" for label, rate in single]
    chunks.append("\n".join(lines))
    print(chunks[-1] + "\n", file=stream, flush=True)

    for mode in ("pd", "voltage"):
        chunks.append(format_cost(bench_cost(steps=200 if quick else 3000, control_mode=mode), mode))
        print(chunks[-1] + "\n", file=stream, flush=True)

    sizes = (8, 64) if quick else (64, 1024, 4096)
    vector = bench_vector(sizes, 3 if quick else 20)
    lines = ["Native vector environment (random actions), gym.make_vec vector_entry_point:",
             "| env id | control_mode | N | steps/s | CartPole-v1 steps/s | ratio |", "|---|---|---|---|---|---|"]
    lines += [f"| {env_id} | {mode} | {n} | {ours:,.0f} | {cart:,.0f} | {ours / cart:.4f} |"
              for env_id, mode, n, ours, cart in vector]
    chunks.append("\n".join(lines))
    print(chunks[-1] + "\n", file=stream, flush=True)

    lines = ["Loop-count divergence of a one-thread-per-robot GPU step (CPU env, N = 4,096 in warps of 32, "
             "random actions; branches inside a step not counted):",
             "| control_mode | SIMT efficiency | sorted by the previous step's work | RHS per step: mean, largest |",
             "|---|---|---|---|"]
    for mode in ("voltage", "pd"):
        bound = bench_warp_bound(mode, n=1024 if quick else 4096, steps=10 if quick else 60)
        lines.append(f"| {mode} | {bound['efficiency']:.2f} | {bound['sorted_efficiency']:.2f} | "
                     f"{bound['mean_work']:.0f}, {bound['largest_work']} |")
    chunks.append("\n".join(lines))
    print(chunks[-1] + "\n", file=stream, flush=True)

    rows = bench_tolerance(20 if quick else 300)
    title = ("Integration tolerance of the environment: speed against accuracy (one random-action "
             "voltage-mode episode, one env, errors against rtol 1e-10, atol 1e-12):")
    lines = [title,
             "| rtol | atol | steps/s | RHS evaluations per step | largest joint error [rad or m] |",
             "|---|---|---|---|---|"]
    lines += [f"| {row['rtol']:g} | {row['atol']:g} | {row['rate']:,.0f} | {row['rhs']:.1f} | {row['error']:.1e} |"
              for row in rows]
    chunks.append("\n".join(lines))
    print(chunks[-1] + "\n", file=stream, flush=True)

    n_memory = sizes[-1]
    env_peak, process_peak = bench_memory(n_memory)
    cold, warm = bench_start()
    chunks.append(f"Peak memory, vector env with N = {n_memory}: {env_peak:.1f} MiB allocated by the env "
                  f"and 20 steps (tracemalloc); the whole process peaks at {process_peak:.0f} MiB RSS "
                  f"(Python, numpy, scipy, numba, LLVM)\n"
                  f"Start, import + gym.make + reset + first step in a fresh process: "
                  f"cold (empty JIT cache) {cold:.1f} s, warm (cached) {warm:.2f} s")
    print(chunks[-1] + "\n", file=stream, flush=True)

    chunks.append(gpu_section(quick, stream))
    return "\n\n".join(chunks)


def gpu_section(quick: bool, stream) -> str:
    why_not = gpu_available()
    if why_not is not None:
        text = f"GPU: skipped: {why_not}"
    else:
        rows = bench_gpu(GPU_SIZES[:2] if quick else GPU_SIZES, 10 if quick else 50)
        lines = ["CUDA vector environment (device='cuda', random voltage actions, Scara-C11-v1):",
                 "| N | robot-steps/s | largest |q| difference to the CPU env after the steps |", "|---|---|---|"]
        lines += [f"| {row['n']:,} | {row['rate']:,.0f} | {row['q_difference']:.1e} |" for row in rows]
        text = "\n".join(lines)
    print(text, file=stream, flush=True)
    return text
