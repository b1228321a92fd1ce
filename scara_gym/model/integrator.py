"""Compiled hybrid integrator: Dormand-Prince 5(4) with located mode switches.

The C11 model is piecewise smooth. Current limits, the critical condition of the
obstacle rule, the wall plane, the height of the wall and the target band each
switch a discrete mode; each mode has an event function ``g`` that is positive
while the mode holds. After every accepted step a sign change of some ``g`` is
located on the step's quartic dense output (the same polynomial as scipy's RK45)
by the Illinois method to 1e-12 s; the step is cut there, the mode switched, and
integration restarts from the event. The voltage saturation of the PD law is only
a kink (continuous right-hand side) and is left to step-size control.

Error control is scipy's: RMS norm of the embedded error over
``atol + rtol * max(|y_old|, |y_new|)``, so "the same tolerances" means the same
thing here and in ``solve_ivp``.

Interfaces are the records of :mod:`scara_gym.model.records`: ``integrate(robot, p,
config, t_end, log, samples)`` advances one ``ROBOT`` record under a ``PARAMS`` and a
``CONFIG`` record, writes events to ``log`` (an ``EVENT`` array) and, unless ``samples``
is None, samples to a ``SAMPLE`` array. Its only allocation is one fixed-size work
buffer per call (a local array on a GPU).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from scara_gym.model.compilation import JIT, JIT_INLINE
from scara_gym.model.dynamics import (
    derivative, free_current_rate, is_critical_state, is_inside_target, target_error, tip_position,
    voltages,
)
from scara_gym.model.records import (
    CRIT_FORCED, CRIT_SWITCH, CURRENT, E_CRITICAL, E_HEIGHT, E_SIDE, E_TARGET, EV_ABOVE, EV_BELOW,
    EV_COLLISION, EV_CRITICAL_OFF, EV_CRITICAL_ON, EV_LIMIT_OFF, EV_LIMIT_ON, EV_TARGET_IN,
    EV_TARGET_OUT, EV_WALL_CROSS, N_EVENTS, N_STATE, Q, RATE, STATUS_END, STATUS_MAX_STEPS,
    STATUS_NOT_FINITE, STATUS_STEP_UNDERFLOW, STATUS_STOPPED, STOP_ABOVE, STOP_COLLISION,
    STOP_CRITICAL, STOP_TARGET,
)

# Dormand-Prince 5(4) tableau and Shampine's dense output, as in scipy.integrate.RK45
RK_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0])
RK_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0],
    [1 / 5, 0.0, 0.0, 0.0, 0.0],
    [3 / 40, 9 / 40, 0.0, 0.0, 0.0],
    [44 / 45, -56 / 15, 32 / 9, 0.0, 0.0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0.0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
])
RK_B = np.array([35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
RK_E = np.array([-71 / 57600, 0.0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
RK_P = np.array([
    [1.0, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
    [0.0, 0.0, 0.0, 0.0],
    [0.0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
    [0.0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
    [0.0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
    [0.0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
    [0.0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
])
# the same coefficients as scalars, for the written-out stages
A21 = RK_A[1, 0]
A31, A32 = RK_A[2, 0], RK_A[2, 1]
A41, A42, A43 = RK_A[3, 0], RK_A[3, 1], RK_A[3, 2]
A51, A52, A53, A54 = RK_A[4, 0], RK_A[4, 1], RK_A[4, 2], RK_A[4, 3]
A61, A62, A63, A64, A65 = RK_A[5, 0], RK_A[5, 1], RK_A[5, 2], RK_A[5, 3], RK_A[5, 4]
B1, B3, B4, B5, B6 = RK_B[0], RK_B[2], RK_B[3], RK_B[4], RK_B[5]
E1, E3, E4, E5, E6, E7 = RK_E[0], RK_E[2], RK_E[3], RK_E[4], RK_E[5], RK_E[6]
SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0
EVENT_TIME_TOL = 1e-12  # [s] width of the bracket an event is located to


@njit(**JIT_INLINE)
def event_values(x, robot, p, config, volts, g):
    """g_k(x) for every mode switch, positive while the robot's current mode holds."""
    voltages(x, robot, p, config, volts)
    for axis in range(3):
        imax = p.current_limit[axis]
        hold = robot.hold[axis]
        if hold == 0:
            g[axis] = imax - abs(x[CURRENT + axis])
        else:  # held: stays held while the free dynamics push outward
            g[axis] = hold * free_current_rate(volts[axis], x[RATE + axis], hold * imax, p, axis)
    x_tip, _, _ = tip_position(x[Q], x[Q + 1], x[Q + 2], p)
    if config.critical_rule == CRIT_SWITCH:
        measure = min(p.critical_distance - abs(x_tip - p.wall_x), p.wall_height - x[Q + 2])  # > 0 iff critical
        g[E_CRITICAL] = measure if robot.critical == 1 else -measure
    else:
        g[E_CRITICAL] = 1.0
    g[E_SIDE] = robot.side * (x_tip - p.wall_x) if config.wall else 1.0
    g[E_HEIGHT] = (x[Q + 2] - p.wall_height) if robot.above == 1 else (p.wall_height - x[Q + 2])
    error = target_error(x, p)
    g[E_TARGET] = (p.accuracy - error) if robot.inside == 1 else (error - p.accuracy)
    return g


@njit(**JIT)
def log_event(t, code, axis, robot, log):
    n = robot.n_events
    if n < log.shape[0]:
        log[n].time = t
        log[n].code = code
        log[n].axis = axis
    robot.n_events = n + 1


@njit(**JIT)
def initial_modes(robot, p, config):
    """Discrete modes implied by the robot's state at the start of a simulation."""
    x = robot.x
    for axis in range(3):
        robot.hold[axis] = 0
    if config.critical_rule == CRIT_FORCED:
        robot.critical = 1
    elif config.critical_rule == CRIT_SWITCH:
        robot.critical = 1 if is_critical_state(x, p) else 0
    else:
        robot.critical = 0
    x_tip, _, _ = tip_position(x[Q], x[Q + 1], x[Q + 2], p)
    robot.side = 1 if x_tip >= p.wall_x else -1
    robot.above = 1 if x[Q + 2] >= p.wall_height else 0
    robot.inside = 1 if is_inside_target(x, p) else 0


@njit(**JIT)
def settle_holds(t, x, robot, p, config, volts, log):
    """Hold a current at its limit while it pushes outward; release it when it no longer does.

    Needed at the start of every call (a new command can reverse the push) and after events.
    """
    voltages(x, robot, p, config, volts)
    for axis in range(3):
        imax = p.current_limit[axis]
        current = x[CURRENT + axis]
        if robot.hold[axis] == 0 and abs(current) > imax:
            sign = 1 if current > 0 else -1
            if sign * free_current_rate(volts[axis], x[RATE + axis], sign * imax, p, axis) >= 0.0:
                robot.hold[axis] = sign
                log_event(t, EV_LIMIT_ON, axis, robot, log)
            x[CURRENT + axis] = sign * imax
        elif robot.hold[axis] != 0:
            x[CURRENT + axis] = robot.hold[axis] * imax
            if robot.hold[axis] * free_current_rate(volts[axis], x[RATE + axis], x[CURRENT + axis], p, axis) < 0.0:
                robot.hold[axis] = 0
                log_event(t, EV_LIMIT_OFF, axis, robot, log)


@njit(**JIT)
def handle_event(k, t, x, robot, p, config, log):
    """Switch the mode of event k at state x; True when the configuration says stop here."""
    stop_mask = config.stops
    stop = False
    axis = -1
    if k < 3:
        axis = k
        if robot.hold[k] == 0:
            sign = 1 if x[CURRENT + k] > 0 else -1
            robot.hold[k] = sign
            x[CURRENT + k] = sign * p.current_limit[k]
            code = EV_LIMIT_ON
        else:
            robot.hold[k] = 0
            code = EV_LIMIT_OFF
    elif k == E_CRITICAL:
        robot.critical = 1 - robot.critical
        code = EV_CRITICAL_ON if robot.critical == 1 else EV_CRITICAL_OFF
        stop = code == EV_CRITICAL_ON and (stop_mask & STOP_CRITICAL) != 0
    elif k == E_SIDE:
        robot.side = -robot.side
        code = EV_COLLISION if x[Q + 2] < p.wall_height else EV_WALL_CROSS
        stop = code == EV_COLLISION and (stop_mask & STOP_COLLISION) != 0
    elif k == E_HEIGHT:
        robot.above = 1 - robot.above
        code = EV_ABOVE if robot.above == 1 else EV_BELOW
        stop = code == EV_ABOVE and (stop_mask & STOP_ABOVE) != 0
    else:
        robot.inside = 1 - robot.inside
        code = EV_TARGET_IN if robot.inside == 1 else EV_TARGET_OUT
        stop = code == EV_TARGET_IN and (stop_mask & STOP_TARGET) != 0
    log_event(t, code, axis, robot, log)
    if stop:
        robot.stop_event = code
    return stop


@njit(**JIT_INLINE)
def rms_norm(values, scale):
    total = 0.0
    for i in range(values.shape[0]):
        ratio = values[i] / scale[i]
        total += ratio * ratio
    return math.sqrt(total / values.shape[0])


@njit(**JIT_INLINE)
def dense_weight(s, theta):
    """Weight of stage s in the dense output at theta: row s of RK_P as a polynomial."""
    return theta * (RK_P[s, 0] + theta * (RK_P[s, 1] + theta * (RK_P[s, 2] + theta * RK_P[s, 3])))


@njit(**JIT_INLINE)
def dense_output(x, h, k, theta, out):
    """State at t + theta h from the step's stages (quartic in theta)."""
    b0 = dense_weight(0, theta)
    b2 = dense_weight(2, theta)
    b3 = dense_weight(3, theta)
    b4 = dense_weight(4, theta)
    b5 = dense_weight(5, theta)
    b6 = dense_weight(6, theta)
    for i in range(x.shape[0]):  # row 1 of RK_P is zero
        out[i] = x[i] + h * (k[0, i] * b0 + k[2, i] * b2 + k[3, i] * b3 + k[4, i] * b4
                             + k[5, i] * b5 + k[6, i] * b6)
    return out


@njit(**JIT)
def initial_step(x, f0, robot, p, config, volts, scale, y1, f1):
    """Hairer's starting step, as scipy's select_initial_step (order 5); scale, y1 and f1
    are work vectors of the state's size."""
    n = x.shape[0]
    rtol, atol = config.rtol, config.atol
    for i in range(n):
        scale[i] = atol + rtol * abs(x[i])
    d0 = rms_norm(x, scale)
    d1 = rms_norm(f0, scale)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    for i in range(n):
        y1[i] = x[i] + h0 * f0[i]
    derivative(y1, robot, p, config, f1, volts)
    for i in range(n):
        f1[i] = f1[i] - f0[i]
    d2 = rms_norm(f1, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 5.0)
    return min(100.0 * h0, h1)


@njit(**JIT_INLINE)
def record(t, x, robot, p, config, volts, samples):
    n = robot.n_samples
    if n < samples.shape[0]:
        voltages(x, robot, p, config, volts)
        sample = samples[n]
        sample.t = t
        sample.x[:] = x
        sample.voltage[:] = volts
        robot.n_samples = n + 1


@njit(**JIT)
def integrate(robot, p, config, t_end, log, samples):
    """Advance the robot (in place) from robot.t to t_end or to the first stop event.

    The robot's hybrid modes are in/out (fill them with initial_modes once per
    simulation), and so is its step size, so that consecutive calls keep it. samples:
    a SAMPLE array, or None to record nothing. Returns the status; robot.t is the time
    reached.
    """
    n = N_STATE
    work = np.empty((12, n))  # one allocation per call: this runs once per control step
    k = work[:7]
    y_new = work[7]
    y_stage = work[8]
    x_event = work[9]
    scale = work[10]
    err_vec = work[11]
    small = np.empty((4, N_EVENTS))
    volts = small[3, :3]
    g_old = small[0]
    g_new = small[1]
    g_try = small[2]
    triggered = np.zeros(N_EVENTS, dtype=np.bool_)
    x = robot.x
    rtol, atol = config.rtol, config.atol

    t = robot.t
    settle_holds(t, x, robot, p, config, volts, log)
    if samples is not None and robot.n_samples == 0:
        record(t, x, robot, p, config, volts, samples)
    derivative(x, robot, p, config, k[0], volts)
    robot.n_rhs += 1
    event_values(x, robot, p, config, volts, g_old)
    h = robot.step_size
    h_max = robot.max_step
    if h <= 0.0:
        h = initial_step(x, k[0], robot, p, config, volts, scale, y_stage, y_new)
        robot.n_rhs += 1
    budget = config.max_steps
    attempts = 0
    while t < t_end:
        if attempts >= budget:
            robot.step_size = h
            robot.t = t
            return STATUS_MAX_STEPS
        attempts += 1
        h_step = min(h, h_max, t_end - t)
        last = h_step >= t_end - t
        # Dormand-Prince stages, written out (row j of RK_A, RK_B, RK_E; zero entries left out)
        for i in range(n):
            y_stage[i] = x[i] + h_step * (A21 * k[0, i])
        derivative(y_stage, robot, p, config, k[1], volts)
        for i in range(n):
            y_stage[i] = x[i] + h_step * (A31 * k[0, i] + A32 * k[1, i])
        derivative(y_stage, robot, p, config, k[2], volts)
        for i in range(n):
            y_stage[i] = x[i] + h_step * (A41 * k[0, i] + A42 * k[1, i] + A43 * k[2, i])
        derivative(y_stage, robot, p, config, k[3], volts)
        for i in range(n):
            y_stage[i] = x[i] + h_step * (A51 * k[0, i] + A52 * k[1, i] + A53 * k[2, i] + A54 * k[3, i])
        derivative(y_stage, robot, p, config, k[4], volts)
        for i in range(n):
            y_stage[i] = x[i] + h_step * (A61 * k[0, i] + A62 * k[1, i] + A63 * k[2, i] + A64 * k[3, i]
                                          + A65 * k[4, i])
        derivative(y_stage, robot, p, config, k[5], volts)
        for i in range(n):
            y_new[i] = x[i] + h_step * (B1 * k[0, i] + B3 * k[2, i] + B4 * k[3, i] + B5 * k[4, i]
                                        + B6 * k[5, i])
        derivative(y_new, robot, p, config, k[6], volts)
        robot.n_rhs += 6
        for i in range(n):
            err_vec[i] = h_step * (E1 * k[0, i] + E3 * k[2, i] + E4 * k[3, i] + E5 * k[4, i]
                                   + E6 * k[5, i] + E7 * k[6, i])
            scale[i] = atol + rtol * max(abs(x[i]), abs(y_new[i]))
        err = rms_norm(err_vec, scale)
        if not math.isfinite(err):
            h = 0.1 * h_step
            robot.n_rejected += 1
            if h < 1e-14 * max(1.0, abs(t)):
                robot.step_size = h
                robot.t = t
                return STATUS_NOT_FINITE
            continue
        if err > 1.0:
            h = h_step * max(MIN_FACTOR, SAFETY * err ** -0.2)
            robot.n_rejected += 1
            if h < 1e-14 * max(1.0, abs(t)):
                robot.step_size = h
                robot.t = t
                return STATUS_STEP_UNDERFLOW
            continue
        robot.n_steps += 1
        factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** -0.2)

        event_values(y_new, robot, p, config, volts, g_new)
        any_event = False
        for e in range(N_EVENTS):
            triggered[e] = g_old[e] >= 0.0 and g_new[e] < 0.0
            any_event = any_event or triggered[e]
        if not any_event:
            t = t_end if last else t + h_step
            x[:] = y_new
            k[0, :] = k[6, :]
            g_old[:] = g_new
            h = max(h, h_step * factor) if last else h_step * factor
            if samples is not None:
                record(t, x, robot, p, config, volts, samples)
            continue

        # locate the earliest event on the dense output (Illinois), bracket [lo, hi] in theta
        theta_first = 1.0
        for e in range(N_EVENTS):
            if not triggered[e]:
                continue
            lo, hi = 0.0, 1.0
            g_lo, g_hi = g_old[e], g_new[e]
            side = 0
            for _ in range(200):
                if (hi - lo) * h_step <= EVENT_TIME_TOL:
                    break
                theta = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
                if not (lo < theta < hi):
                    theta = 0.5 * (lo + hi)
                dense_output(x, h_step, k, theta, x_event)
                event_values(x_event, robot, p, config, volts, g_try)
                g_mid = g_try[e]
                if g_mid < 0.0:
                    hi, g_hi = theta, g_mid
                    if side == -1:
                        g_lo *= 0.5
                    side = -1
                else:
                    lo, g_lo = theta, g_mid
                    if side == 1:
                        g_hi *= 0.5
                    side = 1
            theta_first = min(theta_first, hi)
        if theta_first >= 1.0:
            x_event[:] = y_new
        else:
            dense_output(x, h_step, k, theta_first, x_event)
        event_values(x_event, robot, p, config, volts, g_try)
        t = t_end if (last and theta_first >= 1.0) else t + theta_first * h_step
        x[:] = x_event
        stop = False
        for e in range(N_EVENTS):
            if triggered[e] and g_try[e] < 0.0:
                stop = handle_event(e, t, x, robot, p, config, log) or stop
        settle_holds(t, x, robot, p, config, volts, log)
        if samples is not None:
            record(t, x, robot, p, config, volts, samples)
        derivative(x, robot, p, config, k[0], volts)
        robot.n_rhs += 1
        event_values(x, robot, p, config, volts, g_old)
        h = h_step  # the step up to the event was accurate; keep its size
        if stop:
            robot.step_size = h
            robot.t = t
            return STATUS_STOPPED
    robot.step_size = h
    robot.t = t
    return STATUS_END


# entry points for Python callers: one-element record arrays dispatch faster than records
@njit(**JIT)
def advance(robots, params, configs, t_end, log, samples):
    """integrate() on element 0 of the record arrays; samples may be None."""
    return integrate(robots[0], params[0], configs[0], t_end, log, samples)


@njit(**JIT)
def start(robots, params, configs):
    """initial_modes() on element 0 of the record arrays."""
    initial_modes(robots[0], params[0], configs[0])
