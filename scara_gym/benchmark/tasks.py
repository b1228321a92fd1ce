"""The benchmark tasks of the seed paper (ARGESIM C11, sections 1-3).

a. `compare_forms`: implicit vs explicit form, same results, runtimes compared.
b. `point_to_point`: (0, 0, 0) -> (2, 2, 0.3) with a located stop event at acc.
c. `obstacle_avoidance`: the ``dec`` rule in the seed's two variants
   ("restart", the seed's MATLAB version, and "continuous", its Simulink version),
   and "none" (plain PD, which hits the wall).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from scara_gym.model import checks
from scara_gym.model.params import DEFAULT_PARAMS, ScaraParams, resolve_params
from scara_gym.model.simulator import (
    REFERENCE_ATOL,
    REFERENCE_RTOL,
    Simulator,
    Trajectory,
    check_state,
    start_state,
)

VARIANTS = ("restart", "continuous", "none")


def _end_time(t_end) -> float:
    return checks.real("t_end", t_end, 0.0, 1000.0, unit="s", low_open=True)


def point_to_point(params: ScaraParams = DEFAULT_PARAMS, *, form: str = "explicit",
                   rtol: float = REFERENCE_RTOL, atol: float = REFERENCE_ATOL,
                   t_end: float = 5.0, q0=None, wall: bool = False) -> Trajectory:
    """Task b: PD point-to-point move from the task's start, stopped when all |q_i - q^_i| < acc.

    Args:
        params: the parameter tree (default: the C11 set).
        form: "explicit" (analytic inverse of the mass matrix) or "implicit" (linear solve).
        rtol: relative integration tolerance (scipy's meaning).
        atol: absolute integration tolerance.
        t_end: the longest simulated time [s].
        q0 (sequence of 3 floats | None): the start [rad, rad, m]; None: the task's.
        wall: locate crossings of the wall plane (the move ignores the wall).

    Returns:
        The Trajectory: ``reach_time``, located ``events``, samples and the ``tip`` path.
    """
    t_end = _end_time(t_end)
    sim = Simulator(params, form=form, wall=wall, stop=("target",), rtol=rtol, atol=atol)
    sim.reset(start_state(params, q0), command=params.task.target)
    started = time.perf_counter()
    status = sim.advance(t_end)
    return sim.trajectory(status, time.perf_counter() - started)


def sample_point_to_point(times, params: ScaraParams = DEFAULT_PARAMS, *, form: str = "explicit",
                          rtol: float = REFERENCE_RTOL, atol: float = REFERENCE_ATOL) -> np.ndarray:
    """States of task b (without the stop) at the given increasing times, shape (len(times), 10)."""
    sim = Simulator(params, form=form, stop=(), rtol=rtol, atol=atol, record=0)
    sim.reset(start_state(params), command=params.task.target)
    out = []
    for t in np.asarray(times, dtype=float):
        sim.advance(t)
        out.append(sim.x.copy())
    return np.array(out)


@dataclass(frozen=True)
class FormComparison:
    """The explicit and the implicit form of the model side by side on task b (compare_forms)."""
    runtime_explicit: float
    """Best of the repeats, task b to the stop event [s]."""
    runtime_implicit: float
    reach_time_explicit: float
    reach_time_implicit: float
    max_relative_difference: float
    """max |x_impl - x_expl| / max(|x_expl|, 1e-3) over a 1 ms grid."""


def compare_forms(params: ScaraParams = DEFAULT_PARAMS, *, repeats: int = 5,
                  rtol: float = REFERENCE_RTOL, atol: float = REFERENCE_ATOL) -> FormComparison:
    """Task a: same model, analytic inverse vs linear solve per evaluation.

    Args:
        params: the parameter tree (default: the C11 set).
        repeats: timed runs of each form (the best counts).
        rtol: relative integration tolerance.
        atol: absolute integration tolerance.

    Returns:
        The FormComparison: each form's runtime and the largest relative difference of the
        two trajectories.
    """
    repeats = checks.integer("repeats", repeats, 1)
    runs = {}
    for form in ("explicit", "implicit"):
        point_to_point(params, form=form, rtol=rtol, atol=atol)  # compile / warm up
        runs[form] = [point_to_point(params, form=form, rtol=rtol, atol=atol) for _ in range(repeats)]
    grid = np.linspace(0.0, runs["explicit"][0].reach_time, 1571)
    expl = sample_point_to_point(grid, params, form="explicit", rtol=rtol, atol=atol)
    impl = sample_point_to_point(grid, params, form="implicit", rtol=rtol, atol=atol)
    relative = np.abs(impl - expl) / np.maximum(np.abs(expl), 1e-3)
    return FormComparison(
        runtime_explicit=min(r.stats["runtime"] for r in runs["explicit"]),
        runtime_implicit=min(r.stats["runtime"] for r in runs["implicit"]),
        reach_time_explicit=runs["explicit"][0].reach_time,
        reach_time_implicit=runs["implicit"][0].reach_time,
        max_relative_difference=float(relative.max()),
    )


def obstacle_avoidance(params: ScaraParams = DEFAULT_PARAMS, *, variant: str = "restart",
                       dec: float | None = None, form: str = "explicit",
                       rtol: float = REFERENCE_RTOL, atol: float = REFERENCE_ATOL,
                       t_end: float = 5.0, stop_on_collision: bool = False) -> Trajectory:
    """Task c: the move of task b with the wall in the way, avoided by the seed's ``dec`` rule.

    Collisions (the tip crossing x = x_obs while q3 < h_obs) are located and logged; the run
    goes on through them unless ``stop_on_collision``.

    Args:
        params: the parameter tree (default: the C11 set).
        variant: "restart": stop at the critical event, continue with the decelerated model
            (q1' = dec v1, q2' = dec v2, voltages up to Umax_wide) until q3 >= h_obs, then
            restart plain point-to-point from the reached positions with rates and currents
            set to zero (the seed's MATLAB version); "continuous": the same switch evaluated
            at every instant, no reset (Simulink); "none": plain PD, no avoidance, the tip
            crosses the wall below h_obs.
        dec: the deceleration factor; None: ``params.obstacle.dec``.
        form: "explicit" or "implicit", as in point_to_point.
        rtol: relative integration tolerance.
        atol: absolute integration tolerance.
        t_end: the longest simulated time [s].
        stop_on_collision: end the run at the first collision.

    Returns:
        The Trajectory, with ``collision_time`` and ``first(event name)``.
    """
    checks.choice("variant", variant, VARIANTS)
    params = resolve_params(params)
    t_end = _end_time(t_end)
    stop_on_collision = checks.flag("stop_on_collision", stop_on_collision)
    if dec is not None:
        params = params.replace({"obstacle.dec": dec})
    stops = ("target", "collision") if stop_on_collision else ("target",)
    common = dict(form=form, rtol=rtol, atol=atol, wall=True)
    x0 = start_state(params)
    target = params.task.target
    started = time.perf_counter()

    if variant == "none":
        sim = Simulator(params, stop=stops, **common)
        sim.reset(x0, command=target)
        status = sim.advance(t_end)
        return sim.trajectory(status, time.perf_counter() - started)

    if variant == "continuous":
        sim = Simulator(params, critical="switch", widen=True, decelerate=True, stop=stops, **common)
        sim.reset(x0, command=target)
        status = sim.advance(t_end)
        return sim.trajectory(status, time.perf_counter() - started)

    parts = []
    approach = Simulator(params, critical="switch", widen=True, decelerate=True,
                         stop=stops + ("critical",), **common)
    approach.reset(x0, command=target)
    status = approach.advance(t_end)
    parts.append(approach.trajectory(status))
    if parts[-1].status == "critical":
        climb = Simulator(params, critical="forced", widen=True, decelerate=True,
                          stop=stops + ("above",), **common)
        climb.reset(approach.x, t0=approach.t, command=target)
        status = climb.advance(t_end)
        parts.append(climb.trajectory(status))
        if parts[-1].status == "above":
            # the seed resets rates and currents: the decelerated end state is not a
            # consistent initial value of the point-to-point model
            restart = check_state("restart state", climb.x).copy()
            restart[3:9] = 0.0
            final = Simulator(params, stop=stops, **common)
            final.reset(restart, t0=climb.t, command=target)
            status = final.advance(t_end)
            parts.append(final.trajectory(status))
    result = Trajectory.concatenate(parts)
    result.stats["runtime"] = time.perf_counter() - started
    return result
