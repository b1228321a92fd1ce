# Lab notebook, not maintained (lab/README.md): written for one entry of docs/experiments.md, on the code of its day.
"""Per-group tolerance weights in the hybrid integrator: accuracy at `scara-c11 accuracy`'s targets
and the right-hand sides per control step, against v2's plain tolerances (the experiments log,
2026-12-03, "Weighting the tolerances by state group").

    PYTHONPATH=. python lab/tolerance_weights.py [SEEDS]

Accuracy over SEEDS x 200 episodes (seeds 0..SEEDS-1 of the episode plans) against the unweighted
rtol 1e-10 run, at v2's rtol 1e-7 / atol 1e-9; then the compiled step's time per control step
(best of 3 passes over 1,500 seeded random actions) beside v0's and v2's, in one sitting.
"""

import sys

from scara_gym.benchmark.accuracy import TARGETS, run, summary
from scara_gym.benchmark.bench import _compiled_run
from scara_gym.envs import ScaraEnv

CANDIDATES = [None, {"q": 0.1, "current": 10}, {"q": 0.03, "current": 30}, {"q": 0.03, "current": 100}]
"""tolerance_weights at v2's rtol 1e-7 / atol 1e-9; None is v2 itself"""


class _Spec:
    id = "candidate"
    max_episode_steps = 300


def compiled_us(mode: str, **kwargs) -> float:
    env = ScaraEnv(control_mode=mode, **kwargs)
    env.spec = _Spec
    return min(_compiled_run(env, 1500)["untimed"] for _ in range(3)) / 1500 * 1e6


def main(seeds: int = 6) -> None:
    for weights in CANDIDATES:
        result = summary([row for seed in range(seeds) for row in run(200, seed, 1e-7, 1e-9, True, weights)])
        text = " ".join(f"{name} {result[name]:.1e} ({len(result['over_target'][name])} over)" for name in TARGETS)
        print(f"weights {weights}: {text}, {result['rhs_per_step']:.1f} RHS per control step", flush=True)
    rows = [("v0", dict(rtol=1e-5, atol=1e-6, exact_switches=False))]
    rows += [(f"v2 {weights}", dict(rtol=1e-7, atol=1e-9, exact_switches=True, tolerance_weights=weights))
             for weights in CANDIDATES]
    for label, kwargs in rows:
        print(f"{label}: compiled step {compiled_us('pd', **kwargs):.1f} us (pd), "
              f"{compiled_us('voltage', **kwargs):.1f} us (voltage)", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 6)
