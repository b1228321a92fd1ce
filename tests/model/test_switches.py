"""Mode switches located inside integration steps (exact_switches): the in-step search on
its own, the PD saturation as a located mode, and the counters a full log cannot lose."""

import numpy as np
import pytest

from scara_gym.model import records as R
from scara_gym.model.integrator import DENSE_SLOPE, RK_P, STACK_DEPTH, first_root_affine
from scara_gym.model.params import DEFAULT_PARAMS
from scara_gym.model.simulator import Simulator, start_state


def quartic(roots_or_coefficients):
    """coeffs[j, 0] = coefficient of theta^(j+1) and g0 of a quartic given in power form."""
    g0, *rest = roots_or_coefficients
    coeffs = np.zeros((4, R.N_STATE))
    coeffs[:, 0] = rest
    return g0, coeffs


def search(power):
    g0, coeffs = quartic(power)
    bracket = np.zeros(4)
    found = first_root_affine(g0, 0, 1.0, -1, 0.0, coeffs, 1e-3, np.zeros((STACK_DEPTH, 7)), bracket)
    return found, bracket[:2].copy()


def first_root(power):
    roots = np.roots(power[::-1])
    real = sorted(r.real for r in roots if abs(r.imag) < 1e-12 and 0.0 <= r.real <= 1.0)
    return real[0] if real else None


@pytest.mark.parametrize("power", [
    (1.0, -0.5, 0.0, 0.0, 0.0),                    # stays positive: 1 - theta / 2
    (0.01, 0.0, 0.0, 0.0, 0.0),                    # constant
    (0.0, 0.3, -0.1, 0.0, 0.0),                    # starts on the boundary, moves inward
])
def test_no_root_no_bracket(power):
    assert first_root(power) in (None, 0.0)
    assert search(power)[0] is False


@pytest.mark.parametrize("power", [
    (0.02, -1.0, 1.0, 0.0, 0.0),                   # dips below zero between 0.02 and 0.98, ends positive
    (0.001, -0.5, 0.5, 0.0, 0.0),                  # a shallow dip, both ends positive
    (0.5, -1.0, 0.0, 0.0, 0.0),                    # crosses once, ends negative
    (0.1, -2.0, 6.0, -4.0, 0.0),                   # dips, comes back, crosses again: the first root counts
    (0.2, -1.6, 3.0, 0.0, -1.5),
])
def test_the_first_root_is_bracketed_even_inside_the_step(power):
    root = first_root(power)
    assert root is not None
    found, (lo, hi) = search(power)
    assert found
    assert lo <= root <= hi
    assert (np.polyval(power[::-1], lo) >= 0.0) and (np.polyval(power[::-1], hi) < 0.0)


def test_dense_slope_bounds_the_dense_output_derivative():
    """|sum_s k_s b_s'(theta)| <= DENSE_SLOPE max |k_s| for random stage values."""
    rng = np.random.default_rng(0)
    theta = np.linspace(0.0, 1.0, 2001)
    weights = np.stack([np.polyval(np.polyder(np.r_[row[::-1], 0.0]), theta) for row in RK_P])
    for _ in range(200):
        k = rng.uniform(-1.0, 1.0, 7)
        assert np.max(np.abs(k @ weights)) <= DENSE_SLOPE * np.max(np.abs(k)) + 1e-12


def task_b(exact_switches, rtol=1e-10, atol=1e-12, max_events=10_000):
    sim = Simulator(DEFAULT_PARAMS, stop=("target",), rtol=rtol, atol=atol, exact_switches=exact_switches,
                    max_events=max_events)
    sim.reset(start_state(DEFAULT_PARAMS), command=DEFAULT_PARAMS.task.target)
    return sim, sim.advance(5.0)


def test_the_pd_saturation_is_a_located_switch():
    sim, status = task_b(True)
    trajectory = sim.trajectory(status)
    kinds = [e.kind for e in trajectory.events]
    assert "voltage_saturation_off" in kinds  # the law starts saturated (a mode, set at the start)
    limits = np.array([p.voltage_limit for p in DEFAULT_PARAMS.axes])
    assert np.all(np.abs(trajectory.voltage) <= limits)
    # the law leaves its bound at the located instant: from there on it is linear in the state
    for event in trajectory.events:
        if event.kind == "voltage_saturation_off":
            row = np.flatnonzero(trajectory.t == event.time)[-1]
            assert abs(trajectory.voltage[row, event.axis]) == pytest.approx(limits[event.axis], rel=1e-9)
    # the same move as the clipped law at tight tolerance, where step-size control resolves the kink
    reference, _ = task_b(False)
    assert trajectory.reach_time == pytest.approx(reference.trajectory(R.STATUS_STOPPED).reach_time, abs=1e-9)


def test_exact_switches_at_the_default_tolerance_follow_the_tight_run_closer():
    tight, _ = task_b(True)
    errors = {}
    for exact in (True, False):
        sim, _ = task_b(exact, rtol=1e-5, atol=1e-6)
        errors[exact] = abs(sim.t - tight.t)
    assert errors[True] < 1e-6
    assert errors[True] < errors[False]


def test_an_overflowing_log_is_reported_and_loses_no_stop():
    sim, status = task_b(True, max_events=2)
    assert status == R.STATUS_STOPPED and sim.status_name(status) == "target"  # the stop status holds
    assert sim.robot["n_events"] > 2
    assert not np.isnan(sim.robot["reach_time"])
    with pytest.raises(RuntimeError, match="event log overflowed"):
        sim.events()


def test_collisions_and_reach_times_are_counted_without_the_log():
    """The environment's step reads the integrator's counters, not its log."""
    from scara_gym.envs.task import ScaraTask

    runs = []
    for log_size in (256, 0):
        task = ScaraTask(control_mode="pd", collision="penalty", exact_switches=True)
        task.log = np.zeros((1, log_size), dtype=R.EVENT)
        task.reset_robot(0, np.random.default_rng(0))
        collisions = []
        for _ in range(60):
            task.step_robot(0, np.array([2 / np.pi, 2 / np.pi, 0.5]))
            collisions.append(int(task.outcomes["collisions"][0]))
        runs.append(collisions)
    assert sum(runs[0]) >= 1  # the plain PD move hits the wall
    assert runs[0] == runs[1]


def test_the_chord_bound_clears_only_steps_without_a_switch_and_more_than_the_slope_bound():
    """chord_clear (the cheap test before first_root_lipschitz's bisection) never clears a step
    whose critical, wall-side or target function dips below zero on the dense output, and it
    clears steps that the slope bound (DENSE_SLOPE) sends to the bisection."""
    from scara_gym.envs.task import ScaraTask
    from scara_gym.model.integrator import BEND, chord_clear, dense_output, event_values, start

    task = ScaraTask(control_mode="pd", exact_switches=True)
    robots, params, configs = task.robots, task.robot_params, task.step_config
    p, config = params[0], configs[0]
    rng = np.random.default_rng(0)
    theta = np.linspace(0.0, 1.0, 401)
    h = 1e-3
    cleared = {e: [0, 0] for e in (R.E_CRITICAL, R.E_SIDE, R.E_TARGET)}  # [by the chord bound only, by both]
    dips = dict.fromkeys(cleared, 0)  # steps along which the function does go below zero
    volts, g, g_new = np.zeros(3), np.zeros(R.N_EVENTS), np.zeros(R.N_EVENTS)
    y, out = np.zeros(R.N_STATE), np.zeros(R.N_STATE)
    for _ in range(1000):
        x = np.zeros(R.N_STATE)
        if rng.random() < 0.5:  # around the target
            x[R.Q:R.Q + 3] = p["target"] + rng.normal(0.0, [0.6, 0.6, 0.1]) * rng.choice([0.01, 0.1])
        else:  # anywhere: tips across the wall's plane, the critical band and the wall's height
            x[R.Q:R.Q + 3] = rng.uniform([-np.pi, -2.5, 0.0], [np.pi, 2.5, 0.4])
        robots[0]["x"] = x
        start(robots, params, configs)
        k = np.zeros((7, R.N_STATE))
        k[:, R.Q:R.Q + 3] = rng.normal(0.0, 1.0, 3) * 20.0 * rng.choice([0.01, 0.1, 1.0]) \
            + rng.normal(0.0, 1.0, (7, 3)) * rng.choice([0.0, 0.1, 1.0])
        dense_output(x, h, k, 1.0, y)
        g_old = event_values(x, robots[0], p, config, volts, g).copy()
        event_values(y, robots[0], p, config, volts, g_new)
        bend = np.zeros(R.N_STATE)
        bend[:R.CURRENT + 3] = h * sum(BEND[s] * np.abs(k[s, :R.CURRENT + 3] - k[0, :R.CURRENT + 3])
                                       for s in range(2, 7))
        reach = DENSE_SLOPE * h * np.max(np.abs(k[[0, 2, 3, 4, 5, 6], R.Q:R.Q + 3]), axis=0)
        tip_slope = p["link1_length"] * reach[0] + p["link2_length"] * (reach[0] + reach[1])
        slopes = {R.E_SIDE: tip_slope, R.E_CRITICAL: max(tip_slope, reach[2]), R.E_TARGET: reach.max()}
        lowest = np.full(R.N_EVENTS, np.inf)
        for t in theta:
            lowest = np.minimum(lowest, event_values(dense_output(x, h, k, t, out), robots[0], p, config, volts, g))
        for e in cleared:
            if g_old[e] < 0.0:
                continue
            dips[e] += lowest[e] < 0.0
            if chord_clear(e, g_old[e], g_new[e], x, y, bend, p):
                assert lowest[e] > 0.0, e
                cleared[e][int(g_old[e] + g_new[e] >= slopes[e])] += 1
    for e, (chord_only, both) in cleared.items():
        assert chord_only > 0 and chord_only + both > 100 and dips[e] > 0, (e, chord_only, both, dips[e])
