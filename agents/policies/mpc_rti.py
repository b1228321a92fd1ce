"""A real-time MPC: the nonlinear MPC's problem (`agents.policies.mpc`), one SQP step per control
step on a structured QP solver (HPIPM), warm-started from the shifted plan.

    scara-agents evaluate --policies mpc-rti --control-mode voltage --condition c11-starts
    python -m agents.policies.mpc_rti c11-starts 8 voltage      # side by side with the MPC (`benchmark`)

The problem is `MPCPolicy`'s, variable for variable and row for row (its ``_bounds``, ``_phases``
and the plan's layout are reused): the voltages held over each step, one Radau IIA element of
degree 3 per step, the current and voltage limits, the wall as phases planned from the previous
plan, the approach rate, the soft (exact-penalty) wall rows, axes 1 and 2 at rest at the horizon's
end below h_obs, and the same cost. Instead of solving it to convergence with IPOPT at every step,
a real-time iteration (Diehl, Bock and Schloeder 2005; acados' SQP_RTI):

- the plan is the last step's, shifted one step on, its first state set to the measured one;
- the collocation equations and the wall rows are linearized at the plan, stage by stage (one
  CasADi function mapped over the stages); the collocation states' deltas are condensed out of
  each stage (a 27 x 27 solve per stage, the "lifted" collocation integrator): what is left is an
  optimal-control QP in the step-start states (9) and each step's voltages and slacks (3 + 4),
  with the wall rows and the currents at the inner collocation points as 15 general rows a stage;
- the cost is quadratic in the plan, so its Hessian is exact; the constraints' curvature is left
  out (Gauss-Newton), which changes how fast the iterations converge, not where to: a fixed point
  of the iteration is a KKT point of the MPC's problem (the test checks it against IPOPT's);
- HPIPM (CasADi's ``hpipm`` conic plugin: a Riccati recursion over the stages, an interior point
  method) solves that QP; the full step is taken, the collocation states expanded from it.

At an episode's first step the plan is the standing state and one step would be far from the
optimum: up to ``first_iterations`` SQP steps are taken there, the phases replanned after each, as
the MPC's ``first_passes``. ``iterations`` > 1 takes more steps at every control step.

``solve_times`` keeps the wall-clock time of each control step's whole computation (the phases,
the bounds, the linearization, the QP, the update), not the QP's alone; ``qp_failures`` counts the
QPs HPIPM did not solve to its tolerance (5-10 % of them, at its 50-iteration limit: the step it
stopped at is taken where it is finite). In a "pd"-mode environment it commands the set-point for
which the PD law gives the planned voltages, as the MPC does.

`benchmark(condition, episodes, mode)` runs the MPC and the RTI on the same episodes (a
condition's tuning draws, or the C11 episode) and prints, per policy, the time per control step
(median, 95th percentile, worst) and the closed-loop outcomes (reach time, success, collisions),
and their ratios. Measured figures: docs/agents.md, "A real-time MPC".
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from agents.policies.mpc import (
    CRITICAL,
    CURRENTS,
    HEIGHT_MARGIN,
    RATES,
    TARGET_ERROR,
    TIP_X,
    WALL_DISTANCE,
    MPCConfig,
    MPCPolicy,
    Q,
    solve_time_summary,
)
from agents.policies.optimal.transcription import radau_coefficients
from scara_gym.benchmark.protocol import get_condition, tuning
from scara_gym.model import checks
from scara_gym.model.checks import UserTypeError
from scara_gym.model.symbolic import symbolic_model

QP_SOLVERS = ("hpipm",)
HPIPM_OPTIONS = {"mode": "speed", "iter_max": 50, "res_g_max": 1e-6, "res_b_max": 1e-6, "res_d_max": 1e-6,
                 "res_m_max": 1e-6}
"""HPIPM's options unless ``qp_options`` overrides them: its "speed" mode, residuals to 1e-6 (tighter
ones took more iterations for steps that differ by 5e-5 V)"""


@dataclass(frozen=True)
class RTIConfig:
    """The real-time iteration (module docstring); ``mpc`` is the problem it iterates on."""

    mpc: MPCConfig = field(default_factory=MPCConfig)
    """the MPC's problem: horizon, margins, phases, weights, penalty, model parameters (its IPOPT
    fields, max_iter, tol, shift_multipliers, first_passes, solver and solver_options, are unused)"""
    iterations: int = 1
    """SQP steps per control step (1: the real-time iteration)"""
    first_iterations: int = 30
    """SQP steps at most at an episode's first control step (from the standing plan)"""
    first_tol: float = 1e-6
    """the first step's iterations stop once a step moves no voltage by more than this fraction of
    its limit and no state by more than this (in the state's units)"""
    regularization: float = 1e-8
    """added to the QP Hessian's diagonal on the states (whose cost is positive semi-definite)"""
    qp_solver: str = "hpipm"
    """CasADi's conic plugin for the QP (HPIPM: its horizon structure is given to it)"""
    qp_inf: float = 1e4
    """what stands for an infinite bound in the QP (CasADi's default, 1e8, left HPIPM at its iteration
    limit on most steps: 100 iterations where 1e4 takes about 20)"""
    qp_options: dict = field(default_factory=dict)
    """options of HPIPM over ``HPIPM_OPTIONS`` (CasADi's ``hpipm`` dict, e.g. {"iter_max": 100})"""

    def __post_init__(self) -> None:
        if not isinstance(self.mpc, MPCConfig):
            raise UserTypeError(f"mpc must be an MPCConfig, got {type(self.mpc).__name__}")
        checks.integer("iterations", self.iterations, 1, 100)
        checks.integer("first_iterations", self.first_iterations, 1, 1000)
        checks.real("first_tol", self.first_tol, 0.0, 1.0, low_open=True)
        checks.real("regularization", self.regularization, 0.0, 1.0)
        checks.real("qp_inf", self.qp_inf, 10.0, 1e20)
        checks.choice("qp_solver", self.qp_solver, QP_SOLVERS)
        if not isinstance(self.qp_options, dict):
            raise UserTypeError(f"qp_options must be a dict of HPIPM options, got {self.qp_options!r}")


class RTIMPCPolicy(MPCPolicy):
    """The MPC's problem by a real-time iteration on HPIPM, in a "voltage"- or "pd"-mode environment
    (module docstring)."""

    name = "mpc-rti"
    NX, NU, NG = 9, 7, 15  # the QP's states, controls (voltages, slacks) and general rows per stage
    INNER_CURRENTS = np.array([6, 7, 8, 15, 16, 17])  # the currents at the inner collocation points, within Z

    def __init__(self, env, config: RTIConfig | None = None) -> None:
        if config is not None and not isinstance(config, RTIConfig):
            raise UserTypeError(f"config must be an RTIConfig or None, got {config!r}")
        self.rti = RTIConfig() if config is None else config
        self.qp_failures = 0
        super().__init__(env, self.rti.mpc)

    # the QP's structure, built once ---------------------------------------------------------
    def _build(self) -> None:
        import casadi as ca

        c, n = self.config, self.config.horizon
        self.model = model = symbolic_model(self.params, control="voltage")
        _, C = radau_coefficients(3)
        # one stage: its start x, voltages U, collocation states Z (the last: the step's end), slacks S
        x, U, Z, S = ca.SX.sym("x", 9), ca.SX.sym("U", 3), ca.SX.sym("Z", 27), ca.SX.sym("S", 4)
        wall_x, wall_height, side = ca.SX.sym("wall_x"), ca.SX.sym("wall_height"), ca.SX.sym("side")
        points = [x, Z[0:9], Z[9:18], Z[18:27]]
        G, h = [], []
        for j in range(1, 4):  # as MPCPolicy._build: the collocation rows, then the wall rows per point
            G.append(sum(C[r, j] * points[r] for r in range(4)) - self.control_dt * model.free(points[j], U))
        for j in range(1, 4):
            q, rates = points[j][:3], points[j][3:6]
            clearance = side * (model.tip(q)[0] - wall_x)
            approach = side * ca.jtimes(model.tip(q)[0], q, rates)
            h.append(ca.vertcat(clearance + S[0] - S[1], points[j][2] - wall_height + S[2] - S[3],
                                approach + c.approach_rate * (clearance - c.wall_margin) + S[0]))
        G, h = ca.vertcat(*G), ca.vertcat(*h)
        stage = ca.Function("stage", [x, U, Z, S, ca.vertcat(wall_x, wall_height, side)],
                            [ca.densify(e) for e in (G, ca.jacobian(G, x), ca.jacobian(G, U), ca.jacobian(G, Z), h,
                                                     ca.jacobian(h, Z), ca.jacobian(h, S))])
        self.linearize = Buffered(stage.map(n, "serial"))
        # the plan's layout, as MPCPolicy's, for predict, _phases, _bounds and _shift
        w = ca.SX.sym("w", self.HEAD + self.STAGE * n)
        end = self.POINTS[-1]
        self.predict = ca.Function("predict", [w], [ca.horzcat(*[w[self.HEAD + self.STAGE * k + end:][:9]
                                                                 for k in range(n)])])  # as MPCPolicy's
        self._build_qp()

    def _build_qp(self) -> None:
        """HPIPM's QP: variables [dx_0, du_0, ..., dx_{N-1}, du_{N-1}, dx_N], rows per stage the
        dynamics' gap (A dx + B du - dx' = -b) then the general rows (D dx + E du in [lb, ub])."""
        import casadi as ca

        n, nx, nu, ng = self.config.horizon, self.NX, self.NU, self.NG
        block = nx + nu
        self.n_var, n_row = block * n + nx, (nx + ng) * n
        rows, cols = [], []
        for k in range(n):
            r, col = (nx + ng) * k, block * k
            # the gap: A (9 x 9) and B's voltage columns (9 x 3), -I on the next state
            rows += [np.repeat(np.arange(r, r + nx), nx + 3)]
            cols += [np.tile(np.arange(col, col + nx + 3), nx)]
            rows += [np.arange(r, r + nx)]
            cols += [np.arange(col + block, col + block + nx)]
            # the general rows: dense in the state and the voltages; the slacks' fixed pattern
            rows += [np.repeat(np.arange(r + nx, r + nx + ng), nx + nu)]
            cols += [np.tile(np.arange(col, col + nx + nu), ng)]
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        self.a_sparsity = ca.Sparsity.triplet(n_row, self.n_var, rows.tolist(), cols.tolist())
        self.a_index = np.empty(rows.size, dtype=int)  # each entry's place among the nonzeros (column-major)
        self.a_index[np.lexsort((rows, cols))] = np.arange(rows.size)
        self.h_sparsity = ca.Sparsity.diag(self.n_var)
        options = {"N": n, "nx": [nx] * (n + 1), "nu": [nu] * n + [0], "ng": [ng] * n + [0],
                   "print_problem": False, "print_time": False, "error_on_fail": False, "inf": self.rti.qp_inf,
                   "hpipm": {**HPIPM_OPTIONS, **self.rti.qp_options}}
        self.qp = ca.conic("rti", self.rti.qp_solver, {"h": self.h_sparsity, "a": self.a_sparsity}, options)
        self.n_row = n_row
        # the cost's Hessian (constant: the cost is quadratic in the plan) and its fixed parts
        c = self.config
        hessian = np.zeros((n + 1, block))
        hessian[:, :nx] = self.rti.regularization
        hessian[1:, :3] += 2 * self.weights
        hessian[:n, nx:nx + 3] = 2 * c.voltage_weight / self.voltage_limit**2
        hessian[:n, nx + 3:] = 2e2 * c.penalty
        self.hessian = ca.DM(self.h_sparsity, hessian.ravel()[:self.n_var])

    # one SQP step ---------------------------------------------------------------------------
    def _sqp_step(self, w: np.ndarray, parameters: np.ndarray, bounds) -> np.ndarray:
        """The QP's step from the plan ``w`` (within its bounds): the step in w's layout."""
        import casadi as ca

        n, nx, nu, ng = self.config.horizon, self.NX, self.NU, self.NG
        c = self.config
        lbx, ubx, lbg, ubg = bounds
        stages = w[self.HEAD:].reshape(n, self.STAGE)
        starts = np.vstack([w[:self.HEAD], stages[:-1, 21:30]])  # each stage's start state
        U, Z, S = stages[:, 0:3], stages[:, 3:30], stages[:, 30:34]
        # the outputs' nonzeros, column-major: stage k's (rows x cols) block is [k, col, row]
        G, Gx, GU, GZ, h, hZ, hS = (v.reshape(n, -1, rows).transpose(0, 2, 1) for v, rows in
                                    zip(self.linearize(starts.ravel(), U.ravel(), Z.ravel(), S.ravel(), np.tile(parameters[3:6], n)),
                                        (27, 27, 27, 27, 9, 9, 9)))
        G, h = G[:, :, 0], h[:, :, 0]  # (n, 27), (n, 9)
        # dZ = a + P dx + R dU: the collocation rows' deltas condensed out of each stage
        solved = np.linalg.solve(GZ, -np.concatenate([G[:, :, None], Gx, GU], axis=2))
        a, P, R = solved[:, :, 0], solved[:, :, 1:10], solved[:, :, 10:13]
        # the gap rows: A = P's last state, B = R's; the general rows: the wall rows, inner currents
        lbg_s = lbg[:-4].reshape(n, 36)[:, 27:]
        ubg_s = ubg[:-4].reshape(n, 36)[:, 27:]
        lbx_s, ubx_s = lbx[self.HEAD:].reshape(n, self.STAGE), ubx[self.HEAD:].reshape(n, self.STAGE)
        D = np.concatenate([hZ @ P, P[:, self.INNER_CURRENTS]], axis=1)  # (n, 15, 9)
        E = np.zeros((n, ng, nu))
        E[:, :9, :3] = hZ @ R
        E[:, :9, 3:] = hS
        E[:, 9:, :3] = R[:, self.INNER_CURRENTS]
        offset = np.concatenate([h + np.einsum("kij,kj->ki", hZ, a), Z[:, self.INNER_CURRENTS]
                                 + a[:, self.INNER_CURRENTS]], axis=1)
        lower = np.concatenate([lbg_s, lbx_s[:, 3 + self.INNER_CURRENTS]], axis=1) - offset
        upper = np.concatenate([ubg_s, ubx_s[:, 3 + self.INNER_CURRENTS]], axis=1) - offset
        values = [np.concatenate([P[:, 18:27], R[:, 18:27]], axis=2).reshape(n, -1), -np.ones((n, nx)),
                  np.concatenate([D, E], axis=2).reshape(n, -1)]
        a_nz = np.empty(self.a_index.size)
        a_nz[self.a_index] = np.concatenate(values, axis=1).ravel()
        gap = -a[:, 18:27]
        lba = np.concatenate([gap, lower], axis=1).ravel()
        uba = np.concatenate([gap, upper], axis=1).ravel()
        # the bounds and the gradient, in the QP's variables
        block = nx + nu
        low, high, grad = (np.zeros((n + 1, block)) for _ in range(3))
        low[:, :nx], high[:, :nx] = -np.inf, np.inf
        low[0, :nx] = high[0, :nx] = 0.0  # the measured state
        ends = stages[:, 21:30]
        low[1:, 6:9], high[1:, 6:9] = lbx_s[:, 27:30] - ends[:, 6:9], ubx_s[:, 27:30] - ends[:, 6:9]
        if np.isfinite(lbg[-4:]).any():  # axes 1 and 2 at rest at the horizon's end
            index = np.array([3, 4, 6, 7])
            low[n, index], high[n, index] = lbg[-4:] - ends[-1, index], ubg[-4:] - ends[-1, index]
        controls = np.concatenate([U, S], axis=1)
        low[:n, nx:] = np.concatenate([lbx_s[:, 0:3], lbx_s[:, 30:34]], axis=1) - controls
        high[:n, nx:] = np.concatenate([ubx_s[:, 0:3], ubx_s[:, 30:34]], axis=1) - controls
        grad[1:, :3] = 2 * self.weights * (ends[:, :3] - parameters[:3])
        grad[:n, nx:nx + 3] = 2 * c.voltage_weight * U / self.voltage_limit**2
        grad[:n, nx + 3:] = c.penalty + 2e2 * c.penalty * S
        size = self.n_var
        solution = self.qp(h=self.hessian, g=grad.ravel()[:size], a=ca.DM(self.a_sparsity, a_nz), lba=lba, uba=uba,
                           lbx=low.ravel()[:size], ubx=high.ravel()[:size])
        d = solution["x"].full().ravel()
        if not self.qp.stats()["success"]:
            self.qp_failures += 1
        if not np.isfinite(d).all():
            return np.zeros_like(w)
        dx = np.append(d, np.zeros(nu)).reshape(n + 1, block)
        dU, dS = dx[:n, nx:nx + 3], dx[:n, nx + 3:]
        dZ = a + np.einsum("kij,kj->ki", P, dx[:n, :nx]) + np.einsum("kij,kj->ki", R, dU)
        step = np.concatenate([dU, dZ, dS], axis=1)
        return np.append(dx[0, :nx], step.ravel())

    # the policy ----------------------------------------------------------------------------
    def __call__(self, obs: np.ndarray) -> np.ndarray:
        started = time.perf_counter()
        obs = np.asarray(obs, dtype=float)
        iterations, first = self.rti.iterations, self.guess is None
        if first:
            self.side = 1.0 if obs[WALL_DISTANCE] >= 0 else -1.0
        x0, parameters, first_limit = self.measured(obs)
        wall_x, wall_height = parameters[3:5]
        if first:
            block = np.concatenate([np.zeros(3), np.tile(x0, 3), np.zeros(4)])
            self.guess = np.append(x0, np.tile(block, self.config.horizon))
            iterations = self.rti.first_iterations
        scale = self._step_scale(first_limit)
        for _ in range(iterations):
            ends = self.predict(self.guess).full().T
            bounds = self._bounds(self._phases(ends, wall_x, wall_height), first_limit, x0)
            guess = np.clip(self.guess, bounds[0], bounds[1])
            step = self._sqp_step(guess, parameters, bounds)
            self.guess = guess + step
            if first and np.max(np.abs(step) / scale) < self.rti.first_tol:
                break
        action = np.clip(self.guess[self.HEAD:][self.VOLTAGES] / first_limit, -1.0, 1.0)
        if self.mode == "pd":  # the set-point for which the PD law gives these voltages at the step's start
            action = self.env.setpoint_action(obs, self.env.pd_setpoint(obs, action))
        self._shift()
        self.solve_times.append(time.perf_counter() - started)
        return action

    def measured(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the problem takes from an observation, as MPCPolicy reads it: the start state
        (currents clipped to their limits), the parameters (target, wall plane, wall height, the
        episode's side of the wall: ``side`` set) and the first step's voltage limits."""
        x0 = np.concatenate([obs[Q], obs[RATES], np.clip(obs[CURRENTS], -self.current_limit, self.current_limit)])
        target = obs[Q] + obs[TARGET_ERROR]
        wall_x, wall_height = obs[TIP_X] - obs[WALL_DISTANCE], obs[Q][2] - obs[HEIGHT_MARGIN]
        first_limit = self.wide_limit if obs[CRITICAL] > 0.5 else self.voltage_limit
        return x0, np.concatenate([target, [wall_x, wall_height, self.side]]), first_limit

    def _step_scale(self, first_limit: np.ndarray) -> np.ndarray:
        """What a step is measured against (first_tol): the voltages' limits, 1 elsewhere."""
        n = self.config.horizon
        scale = np.ones((n, self.STAGE))
        scale[:, self.VOLTAGES] = self.voltage_limit
        return np.append(np.ones(self.HEAD), scale.ravel())


class Buffered:
    """A CasADi function called on numpy arrays through its buffer (no DM conversions: they cost
    more than the QP's factorizations here): the positional arguments' nonzeros in (flat,
    column-major), the outputs' nonzeros out, in arrays that the next call overwrites. Not for
    the QP: CasADi's HPIPM interface called through a buffer returned wrong solutions from its
    second call on."""

    def __init__(self, function) -> None:
        self.function = function
        self.buffer, self.evaluate = function.buffer()
        self.outputs = [np.zeros(function.nnz_out(i)) for i in range(function.n_out())]
        for i, output in enumerate(self.outputs):
            self.buffer.set_res(i, memoryview(output))
        self.inputs = [np.zeros(function.nnz_in(i)) for i in range(function.n_in())]
        for i, array in enumerate(self.inputs):
            self.buffer.set_arg(i, memoryview(array))

    def __call__(self, *args) -> list[np.ndarray]:
        for i, arg in enumerate(args):  # copied into the bound inputs (the rest stay zero)
            self.inputs[i][:] = arg
        self.evaluate()
        return self.outputs


def benchmark(condition: str = "c11-starts", episodes: int = 8, mode: str = "voltage",
              rti: RTIConfig | None = None, mpc: MPCConfig | None = None, out=print) -> dict:
    """The MPC and the real-time MPC on the same episodes, side by side (module docstring).

    Args:
        condition: a protocol condition's name; "c11" runs the C11 episode, any other its tuning
            draws (scara_gym.benchmark.protocol.tuning: never scored seeds).
        episodes: how many tuning draws (ignored for "c11": one episode).
        mode: the environment's control mode, "voltage" or "pd".
        rti, mpc: the two policies' configurations (None: their defaults).
        out: where the lines go.

    Returns:
        policy name -> {"step_time": median/p95/worst [s] of the time per control step (the whole
        call), "reach_times", "success", "collisions" (per episode), "failures" (QPs HPIPM, or
        solves IPOPT, did not converge)}, and "reach_ratio": the RTI's reach time over the MPC's
        on the episodes both ran clean.
    """
    checks.choice("mode", mode, ("voltage", "pd"))
    chosen = get_condition(condition) if condition == "c11" else tuning(condition, episodes)
    results = {}
    for name, make in (("mpc", lambda env: MPCPolicy(env, mpc)), ("mpc-rti", lambda env: RTIMPCPolicy(env, rti))):
        env = chosen.make_env(mode)
        policy = make(env)
        step_times, reach, success, collisions, lengths = [], [], [], [], []
        for seed in chosen.seeds():
            policy.reset()
            obs, info = env.reset(seed=seed, options=chosen.options(seed))
            done = False
            while not done:
                started = time.perf_counter()
                action = policy(obs)
                step_times.append(time.perf_counter() - started)
                obs, _, terminated, truncated, info = env.step(action)
                done = terminated or truncated
            lengths.append(len(step_times) - sum(lengths))
            success.append(bool(info["is_success"]))
            collisions.append(bool(info["collision"]))
            reach.append(float(info["time"]) if info["is_success"] else np.nan)
        env.close()
        failures = policy.qp_failures if isinstance(policy, RTIMPCPolicy) else policy.failures
        results[name] = {"step_time": solve_time_summary(step_times), "reach_times": np.array(reach),
                         "success": np.array(success), "collisions": np.array(collisions), "failures": failures}
        s = results[name]["step_time"]
        later = solve_time_summary(np.delete(step_times, np.cumsum([0, *lengths[:-1]])))
        out(f"{name:8s} {condition} {mode}, {len(success)} episodes: step ms median {1e3 * s['median']:.2f}, p95 "
            f"{1e3 * s['p95']:.2f}, worst {1e3 * s['worst']:.2f} ({s['solves']} steps; after each episode's first: "
            f"worst {1e3 * later['worst']:.2f}) | success {sum(success)}/{len(success)}, collisions "
            f"{sum(collisions)}, mean reach time {np.nanmean(reach):.4f} s | "
            + ("QPs" if name == "mpc-rti" else "IPOPT solves") + f" not converged {failures}")
    a, b = results["mpc"], results["mpc-rti"]
    clean = a["success"] & ~a["collisions"] & b["success"] & ~b["collisions"]
    ratio = b["reach_times"][clean] / a["reach_times"][clean]
    out(f"rti / mpc: step time median x{b['step_time']['median'] / a['step_time']['median']:.3f}, p95 "
        f"x{b['step_time']['p95'] / a['step_time']['p95']:.3f}; reach time on the {int(clean.sum())} episodes both "
        f"run clean: ratio mean {np.mean(ratio) if ratio.size else np.nan:.4f}, worst "
        f"{np.max(ratio) if ratio.size else np.nan:.4f}")
    results["reach_ratio"] = ratio
    return results


if __name__ == "__main__":  # python -m agents.policies.mpc_rti [CONDITION [EPISODES [MODE]]]
    import sys

    benchmark(sys.argv[1] if len(sys.argv) > 1 else "c11-starts", int(sys.argv[2]) if len(sys.argv) > 2 else 8,
              sys.argv[3] if len(sys.argv) > 3 else "voltage", out=lambda line: print(line, flush=True))
