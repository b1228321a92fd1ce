"""DOP853 against DOPRI5 in the hybrid integrator: accuracy at `scara-c11 accuracy`'s targets and
compiled time per control step, side by side (the candidate of "The exact environment at full
speed"; the experiments log, 2026-12-03, has the figures and the verdict).

    PYTHONPATH=. python docs/scripts/hybrid_integrators.py [SEEDS]

Accuracy over SEEDS x 200 episodes (seeds 0..SEEDS-1 of the episode plans) against the rtol 1e-10
DOPRI5 run; time: the compiled step timed from Python (best of 3 passes over 1,500 seeded random
actions), "pd" and "voltage" mode.
"""

import sys
import warnings

from scara_gym.benchmark.accuracy import TARGETS, run, summary
from scara_gym.benchmark.bench import _compiled_run
from scara_gym.envs import ScaraEnv

CANDIDATES = [("dopri5", 1e-5, 1e-6, False), ("dopri5", 1e-7, 1e-9, True), ("dop853", 1e-7, 1e-9, True),
              ("dop853", 5e-8, 5e-10, True), ("dop853", 3e-8, 3e-10, True), ("dop853", 3e-7, 3e-9, True)]
"""(integrator, rtol, atol, exact_switches): v0's and v2's integration, then DOP853 at four tolerances"""


class _Spec:
    id = "candidate"
    max_episode_steps = 300


def main(seeds: int = 3) -> None:
    warnings.simplefilter("ignore", DeprecationWarning)
    for integrator, rtol, atol, exact in CANDIDATES:
        text = "(switches at step ends: not measured)"
        if exact:
            result = summary([row for seed in range(seeds) for row in run(200, seed, rtol, atol, True, integrator)])
            text = " ".join(f"{name} {result[name]:.1e} ({len(result['over_target'][name])} over)" for name in TARGETS)
            text += f", {result['rhs_per_step']:.1f} RHS per control step"
        times = {}
        for mode in ("pd", "voltage"):
            env = ScaraEnv(control_mode=mode, rtol=rtol, atol=atol, exact_switches=exact, integrator=integrator)
            env.spec = _Spec
            times[mode] = min(_compiled_run(env, 1500)["untimed"] for _ in range(3)) / 1500 * 1e6
        print(f"{integrator} {rtol:g} / {atol:g}, exact_switches={exact}: {text}; compiled step "
              f"{times['pd']:.1f} us (pd), {times['voltage']:.1f} us (voltage)", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
