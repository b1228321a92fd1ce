"""The MPC and the real-time MPC side by side on the same episodes (agents.policies.mpc_rti.benchmark):
time per control step (median, 95th percentile, worst) and closed-loop outcomes, and their ratios.

    python docs/scripts/mpc_rti_bench.py c11 1 voltage
    python docs/scripts/mpc_rti_bench.py c11-starts 8 voltage     # the condition's tuning draws

Arguments: the condition ("c11": its one episode; any other: its tuning draws), the number of
episodes, the control mode ("voltage" or "pd"). Run it on one core (e.g. ``taskset -c 0``) for
figures per core.
"""

import sys

from agents.policies.mpc_rti import benchmark

if __name__ == "__main__":
    benchmark(sys.argv[1] if len(sys.argv) > 1 else "c11-starts", int(sys.argv[2]) if len(sys.argv) > 2 else 8,
              sys.argv[3] if len(sys.argv) > 3 else "voltage", out=lambda line: print(line, flush=True))
