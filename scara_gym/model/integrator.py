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

Interfaces are the records of `scara_gym.model.records`: ``integrate(robot, p,
config, t_end, log, samples)`` advances one ``ROBOT`` record under a ``PARAMS`` and a
``CONFIG`` record, writes events to ``log`` (an ``EVENT`` array) and, unless ``samples``
is None, samples to a ``SAMPLE`` array. Its only allocation is one fixed-size work
buffer per call (a local array on a GPU).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir as llvm_ir
from numba import njit, types
from numba.core import cgutils
from numba.core.extending import intrinsic

from scara_gym.model.compilation import JIT, JIT_BORROW, JIT_INLINE
from scara_gym.model.dynamics import (
    applied_voltages,
    derivative,
    free_current_rate,
    is_critical_state,
    is_inside_target,
    is_widened,
    pd_linear_voltage,
    settle_saturation,
    target_error,
    tip_position,
    voltage_limit,
    voltages,
)
from scara_gym.model.records import (
    CONTROL_PD,
    CRIT_FORCED,
    CRIT_SWITCH,
    CURRENT,
    E_CRITICAL,
    E_HEIGHT,
    E_SAT1,
    E_SIDE,
    E_TARGET,
    EV_ABOVE,
    EV_BELOW,
    EV_COLLISION,
    EV_CRITICAL_OFF,
    EV_CRITICAL_ON,
    EV_LIMIT_OFF,
    EV_LIMIT_ON,
    EV_SATURATION_OFF,
    EV_SATURATION_ON,
    EV_TARGET_IN,
    EV_TARGET_OUT,
    EV_WALL_CROSS,
    N_EVENTS,
    N_STATE,
    RATE,
    STATUS_END,
    STATUS_MAX_STEPS,
    STATUS_NOT_FINITE,
    STATUS_STEP_UNDERFLOW,
    STATUS_STOPPED,
    STOP_ABOVE,
    STOP_COLLISION,
    STOP_CRITICAL,
    STOP_TARGET,
    Q,
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
    if config.exact_switches and config.control == CONTROL_PD:
        widened = is_widened(robot, config)
        for axis in range(3):
            limit = voltage_limit(p, axis, widened)
            u = pd_linear_voltage(robot, x, p, axis)
            mode = robot.saturation[axis]
            g[E_SAT1 + axis] = (limit - abs(u)) if mode == 0 else (mode * u - limit)
    else:
        for axis in range(3):  # no saturation modes: they never switch
            g[E_SAT1 + axis] = 1.0
    return g


@njit(**JIT_BORROW)
def log_event(t, code, axis, robot, log):
    n = robot.n_events
    if n < log.shape[0]:
        log[n].time = t
        log[n].code = code
        log[n].axis = axis
    robot.n_events = n + 1


@njit(**JIT_BORROW)
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


@njit(**JIT_BORROW)
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


@njit(**JIT_BORROW)
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
    elif k >= E_SAT1:
        axis = k - E_SAT1
        if robot.saturation[axis] == 0:
            robot.saturation[axis] = 1 if pd_linear_voltage(robot, x, p, axis) > 0.0 else -1
            code = EV_SATURATION_ON
        else:
            robot.saturation[axis] = 0
            code = EV_SATURATION_OFF
    elif k == E_CRITICAL:
        robot.critical = 1 - robot.critical
        code = EV_CRITICAL_ON if robot.critical == 1 else EV_CRITICAL_OFF
        stop = code == EV_CRITICAL_ON and (stop_mask & STOP_CRITICAL) != 0
    elif k == E_SIDE:
        robot.side = -robot.side
        code = EV_COLLISION if x[Q + 2] < p.wall_height else EV_WALL_CROSS
        stop = code == EV_COLLISION and (stop_mask & STOP_COLLISION) != 0
        if code == EV_COLLISION:
            robot.n_collisions += 1
    elif k == E_HEIGHT:
        robot.above = 1 - robot.above
        code = EV_ABOVE if robot.above == 1 else EV_BELOW
        stop = code == EV_ABOVE and (stop_mask & STOP_ABOVE) != 0
    else:
        robot.inside = 1 - robot.inside
        code = EV_TARGET_IN if robot.inside == 1 else EV_TARGET_OUT
        stop = code == EV_TARGET_IN and (stop_mask & STOP_TARGET) != 0
        if code == EV_TARGET_IN and math.isnan(robot.reach_time):
            robot.reach_time = t
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


def _dense_slope() -> float:
    """K with |d/dtheta of the dense output| <= K h max_s |k_s| on [0, 1]: the sum over the
    stages of the largest Bernstein coefficient of each weight's derivative (a cubic).
    """
    total = 0.0
    for p0, p1, p2, p3 in RK_P:
        total += max(abs(p0), abs(p0 + 2 * p1 / 3), abs(p0 + (4 * p1 + 3 * p2) / 3),
                     abs(p0 + 2 * p1 + 3 * p2 + 4 * p3))
    return float(total)


DENSE_SLOPE = _dense_slope()


def _bend_bounds(pieces: int = 256) -> np.ndarray:
    """M_s >= max over [0, 1] of |b_s(theta) - theta b_s(1)|, b_s stage s's dense weight: the
    largest Bernstein coefficient over `pieces` subintervals (a rigorous bound, within 0.1 %
    of the maximum). Since the weights sum to theta, the dense output departs from the chord
    x + theta (y_new - x) by at most h sum_s M_s |k_s - k_0| in each state.
    """
    bounds = np.zeros(len(RK_P))
    for s, row in enumerate(RK_P):
        power = np.zeros(5)  # coefficients of theta^0..theta^4
        power[1:] = row
        power[1] -= row.sum()
        for piece in range(pieces):
            lo, width = piece / pieces, 1.0 / pieces
            # the polynomial on [lo, lo + width] in u in [0, 1]: Taylor shift, then Bernstein
            local = [sum(math.comb(i, j) * power[i] * lo ** (i - j) for i in range(j, 5)) * width ** j
                     for j in range(5)]
            bernstein = [sum(math.comb(j, i) / math.comb(4, i) * local[i] for i in range(j + 1)) for j in range(5)]
            bounds[s] = max(bounds[s], max(abs(c) for c in bernstein))
    return bounds


BEND = _bend_bounds()
SEARCH_RESOLUTION = 1e-10  # [s] a mode switch that starts and ends within less may go unseen
STACK_DEPTH = 64           # intervals of the in-step search (it needs about log2(h / 1e-10) + 1)


@njit(**JIT_BORROW)
def dense_coefficients(h, k, coeffs):
    """coeffs[j, i]: the coefficient of theta^(j+1) in the dense output of state i (a quartic
    in theta with constant term x_i), for the positions, rates and currents.
    """
    for i in range(CURRENT + 3):
        for j in range(4):
            coeffs[j, i] = h * (k[0, i] * RK_P[0, j] + k[2, i] * RK_P[2, j] + k[3, i] * RK_P[3, j]
                                + k[4, i] * RK_P[4, j] + k[5, i] * RK_P[5, j] + k[6, i] * RK_P[6, j])


@njit(**JIT_INLINE)
def affine_bernstein(g0, i1, c1, i2, c2, coeffs):
    """Bernstein coefficients b1..b4 (b0 = g0) on [0, 1] of an event function affine in the
    state: along the step it is the quartic g0 + sum_j (c1 coeffs[j, i1] + c2 coeffs[j, i2])
    theta^(j+1) (i2 < 0: one term).
    """
    p1 = c1 * coeffs[0, i1] + (c2 * coeffs[0, i2] if i2 >= 0 else 0.0)
    p2 = c1 * coeffs[1, i1] + (c2 * coeffs[1, i2] if i2 >= 0 else 0.0)
    p3 = c1 * coeffs[2, i1] + (c2 * coeffs[2, i2] if i2 >= 0 else 0.0)
    p4 = c1 * coeffs[3, i1] + (c2 * coeffs[3, i2] if i2 >= 0 else 0.0)
    return (g0 + p1 / 4.0, g0 + p1 / 2.0 + p2 / 6.0, g0 + 0.75 * p1 + p2 / 2.0 + p3 / 4.0,
            g0 + p1 + p2 + p3 + p4)


@njit(**JIT_BORROW)
def first_root_affine(g0, i1, c1, i2, c2, coeffs, h, stack, bracket):
    """Bracket the first root in [0, 1] of an event function affine in the state, given
    g(0) = g0 >= 0 (see affine_bernstein). Bernstein coefficients bound it on an interval
    (all >= 0: no root there; one sign change: exactly one root). True with bracket[0:2] =
    (lo, hi) around the first root; False when there is none, or only a dip shorter than
    SEARCH_RESOLUTION. The usual case, no root, is decided here without a call.
    """
    b1, b2, b3, b4 = affine_bernstein(g0, i1, c1, i2, c2, coeffs)
    if min(b1, b2, b3, b4) >= 0.0:
        return False
    return refine_root_affine(g0, b1, b2, b3, b4, h, stack, bracket)


@njit(**JIT_INLINE)
def affine_root(g0, i1, c1, i2, c2, x, y_new, bend, h, k, coeffs, ready, stack, bracket):
    """first_root_affine behind a cheaper test: along the step the event function departs
    from the chord between its end values by at most |c1| bend[i1] + |c2| bend[i2] (see
    BEND), so a step whose end values both exceed that has no root, and needs no dense
    coefficients (computed once per step when one is needed). Returns (found, ready: the
    coefficients are computed).
    """
    g1 = g0 + c1 * (y_new[i1] - x[i1]) + (c2 * (y_new[i2] - x[i2]) if i2 >= 0 else 0.0)
    if min(g0, g1) >= abs(c1) * bend[i1] + (abs(c2) * bend[i2] if i2 >= 0 else 0.0):
        return False, ready
    return slow_root_affine(g0, i1, c1, i2, c2, h, k, coeffs, ready, stack, bracket), True


@njit(**JIT_BORROW)
def slow_root_affine(g0, i1, c1, i2, c2, h, k, coeffs, ready, stack, bracket):
    """affine_root past its cheap test: one call, out of line."""
    if not ready:
        dense_coefficients(h, k, coeffs)
    return first_root_affine(g0, i1, c1, i2, c2, coeffs, h, stack, bracket)


@njit(**JIT_BORROW)
def refine_root_affine(g0, b1, b2, b3, b4, h, stack, bracket):
    """first_root_affine's search: de Casteljau halving of the undecided intervals, leftmost
    first.
    """
    top = 0
    stack[0, 0], stack[0, 1] = 0.0, 1.0  # interval start and width in theta, then its Bernstein coefficients
    stack[0, 2], stack[0, 3], stack[0, 4], stack[0, 5], stack[0, 6] = g0, b1, b2, b3, b4
    while top >= 0:
        start, width = stack[top, 0], stack[top, 1]
        b0, b1, b2, b3, b4 = stack[top, 2], stack[top, 3], stack[top, 4], stack[top, 5], stack[top, 6]
        top -= 1
        if min(b1, b2, b3, b4) >= 0.0:
            continue
        changes = ((b0 >= 0.0) != (b1 >= 0.0)) + ((b1 >= 0.0) != (b2 >= 0.0)) \
            + ((b2 >= 0.0) != (b3 >= 0.0)) + ((b3 >= 0.0) != (b4 >= 0.0))
        if b4 < 0.0 and (changes == 1 or width * h <= SEARCH_RESOLUTION):
            bracket[0], bracket[1] = start, start + width
            return True
        if width * h <= SEARCH_RESOLUTION or top + 2 >= stack.shape[0]:
            continue
        # de Casteljau at the middle; the right half goes below the left one on the stack
        l1, m1, n1, o1 = 0.5 * (b0 + b1), 0.5 * (b1 + b2), 0.5 * (b2 + b3), 0.5 * (b3 + b4)
        l2, m2, n2 = 0.5 * (l1 + m1), 0.5 * (m1 + n1), 0.5 * (n1 + o1)
        l3, m3 = 0.5 * (l2 + m2), 0.5 * (m2 + n2)
        l4 = 0.5 * (l3 + m3)
        half = 0.5 * width
        stack[top + 1, 0], stack[top + 1, 1] = start + half, half
        stack[top + 1, 2], stack[top + 1, 3], stack[top + 1, 4] = l4, m3, n2
        stack[top + 1, 5], stack[top + 1, 6] = o1, b4
        stack[top + 2, 0], stack[top + 2, 1] = start, half
        stack[top + 2, 2], stack[top + 2, 3], stack[top + 2, 4] = b0, l1, l2
        stack[top + 2, 5], stack[top + 2, 6] = l3, l4
        top += 2
    return False


@njit(**JIT_BORROW)
def first_root_lipschitz(e, g0, g1, slope, x, h, k, robot, p, config, volts, g_try, x_try, stack, bracket):
    """Bracket the first root in [0, 1] of event function e, not affine in the state, given
    g(0) = g0 >= 0, g(1) = g1 and |dg/dtheta| <= slope: an interval whose end values a, b
    satisfy a + b >= slope * width holds no root; the others are halved, leftmost first, with
    g evaluated on the dense output. True with bracket[0:4] = (lo, hi, g(lo), g(hi)).
    """
    top = 0
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = 0.0, 1.0, g0, g1
    while top >= 0:
        lo, hi, g_lo, g_hi = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        top -= 1
        if g_hi < 0.0:
            bracket[0], bracket[1], bracket[2], bracket[3] = lo, hi, g_lo, g_hi
            return True
        if g_lo + g_hi >= slope * (hi - lo) or (hi - lo) * h <= SEARCH_RESOLUTION \
                or top + 2 >= stack.shape[0]:
            continue
        mid = 0.5 * (lo + hi)
        dense_output(x, h, k, mid, x_try)
        event_values(x_try, robot, p, config, volts, g_try)
        g_mid = g_try[e]
        stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2], stack[top + 1, 3] = mid, hi, g_mid, g_hi
        stack[top + 2, 0], stack[top + 2, 1], stack[top + 2, 2], stack[top + 2, 3] = lo, mid, g_lo, g_mid
        top += 2
    return False


CLEAR_MARGIN = 1e-9  # [m or rad] chord_clear's proof margin: far above the rounding of g on the dense output


@njit(**JIT_INLINE)
def chord_clear(e, g0, g1, x, y_new, bend, p):
    """True when event function e (critical, wall side or target: not affine) provably stays
    above CLEAR_MARGIN along the step, so that first_root_lipschitz would find nothing: a
    cheaper test than its slope bound, and a tighter one, which spares its bisection. Each
    position departs from its chord by at most bend (see BEND), so it is within theta |dq| +
    bend of its start and (1 - theta) |dq| + bend of its end; g is Lipschitz in the positions
    (the tip's x with constants l1 and l2, min, max and abs with 1), so with A and B those
    terms through g, g(theta) >= max(g0 - theta A, g1 - (1 - theta) A) - B >= (g0 + g1 - A) / 2 - B.
    """
    dq1, dq2, dq3 = y_new[Q] - x[Q], y_new[Q + 1] - x[Q + 1], y_new[Q + 2] - x[Q + 2]
    b1, b2, b3 = bend[Q], bend[Q + 1], bend[Q + 2]
    if e == E_TARGET:
        along, off = max(abs(dq1), abs(dq2), abs(dq3)), max(b1, b2, b3)
    else:
        along = p.link1_length * abs(dq1) + p.link2_length * abs(dq1 + dq2)
        off = p.link1_length * b1 + p.link2_length * (b1 + b2)
        if e == E_CRITICAL:
            along, off = max(along, abs(dq3)), max(off, b3)
    return g1 >= 0.0 and 0.5 * (g0 + g1 - along) - off > CLEAR_MARGIN


@njit(**JIT_BORROW)
def search_switches(x, y_new, h, k, robot, p, config, volts, g_old, g_new, g_try, x_try, coeffs, reach,
                    bend, stack, bracket, brackets, triggered):
    """exact_switches: find every mode switch inside the accepted step [t, t + h], including
    one that starts and ends inside it, and bracket its first root for the Illinois
    refinement (brackets rows: lo, hi, g(lo), g(hi), in theta). Switches whose event
    function is affine in the state (current limits, PD saturation, wall height) are
    bracketed exactly on the dense output's quartic; the others (critical, wall side,
    target) with a bound on their slope. True when any switch was found.
    """
    for i in range(Q, Q + 3):  # h max_s |k_s|: with DENSE_SLOPE, a bound on each position's slope
        reach[i] = abs(k[0, i])
        for stage in range(2, 7):
            reach[i] = max(reach[i], abs(k[stage, i]))
        reach[i] *= h
    for i in range(CURRENT + 3):
        bend[i] = h * (BEND[2] * abs(k[2, i] - k[0, i]) + BEND[3] * abs(k[3, i] - k[0, i])
                       + BEND[4] * abs(k[4, i] - k[0, i]) + BEND[5] * abs(k[5, i] - k[0, i])
                       + BEND[6] * abs(k[6, i] - k[0, i]))
    ready = False  # dense coefficients computed
    pd = config.control == CONTROL_PD
    widened = is_widened(robot, config)
    any_event = False
    for e in range(N_EVENTS):
        triggered[e] = False
        if g_old[e] < 0.0:
            continue
        affine = True
        found = False
        if e < 3 or e >= E_SAT1:
            axis = e if e < 3 else e - E_SAT1
            iq, iv, ii = Q + axis, RATE + axis, CURRENT + axis
            gain_p, gain_d = p.p_gain[axis], p.d_gain[axis]
            saturated = robot.saturation[axis] != 0
            if e < 3 and robot.hold[axis] == 0:  # Imax - |I|: two affine pieces
                imax = p.current_limit[axis]
                found, ready = affine_root(imax - x[ii], ii, -1.0, -1, 0.0, x, y_new, bend, h, k, coeffs, ready,
                                           stack, bracket)
                if not found:
                    found, ready = affine_root(imax + x[ii], ii, 1.0, -1, 0.0, x, y_new, bend, h, k, coeffs,
                                               ready, stack, bracket)
            elif e < 3:  # held: hold * I' of the free dynamics, through the voltage and the back-EMF
                s = robot.hold[axis]
                emf = p.torque_constant[axis] * p.gear_ratio[axis]
                inductance = p.inductance[axis]
                if pd and not saturated:
                    found, ready = affine_root(g_old[e], iq, -s * gain_p / inductance, iv,
                                               -s * (gain_d + emf) / inductance, x, y_new, bend, h, k, coeffs,
                                               ready, stack, bracket)
                else:
                    found, ready = affine_root(g_old[e], iv, -s * emf / inductance, -1, 0.0, x, y_new, bend, h,
                                               k, coeffs, ready, stack, bracket)
            elif pd:  # PD saturation, u = P (q^ - q) - D q'
                if not saturated:  # limit - |u|: two affine pieces
                    limit = voltage_limit(p, axis, widened)
                    u = pd_linear_voltage(robot, x, p, axis)
                    found, ready = affine_root(limit - u, iq, gain_p, iv, gain_d, x, y_new, bend, h, k, coeffs,
                                               ready, stack, bracket)
                    if not found:
                        found, ready = affine_root(limit + u, iq, -gain_p, iv, -gain_d, x, y_new, bend, h, k,
                                                   coeffs, ready, stack, bracket)
                else:
                    s = robot.saturation[axis]
                    found, ready = affine_root(g_old[e], iq, -s * gain_p, iv, -s * gain_d, x, y_new, bend, h, k,
                                               coeffs, ready, stack, bracket)
        elif e == E_HEIGHT:
            found, ready = affine_root(g_old[e], Q + 2, 1.0 if robot.above == 1 else -1.0, -1, 0.0, x, y_new,
                                       bend, h, k, coeffs, ready, stack, bracket)
        elif (e == E_CRITICAL and config.critical_rule != CRIT_SWITCH) or (e == E_SIDE and not config.wall):
            continue  # constant: the mode cannot switch
        else:
            affine = False
            d1, d2, d3 = (DENSE_SLOPE * reach[Q], DENSE_SLOPE * reach[Q + 1], DENSE_SLOPE * reach[Q + 2])
            tip_x_slope = p.link1_length * d1 + p.link2_length * (d1 + d2)
            if e == E_SIDE:
                slope = tip_x_slope
            elif e == E_CRITICAL:
                slope = max(tip_x_slope, d3)
            else:
                slope = max(d1, d2, d3)
            if g_new[e] < 0.0 or (g_old[e] + g_new[e] < slope
                                  and not chord_clear(e, g_old[e], g_new[e], x, y_new, bend, p)):
                found = first_root_lipschitz(e, g_old[e], g_new[e], slope, x, h, k, robot, p, config, volts,
                                             g_try, x_try, stack, bracket)
        if not found:
            continue
        lo, hi = bracket[0], bracket[1]
        if affine:  # the event function's own values at the bracket's ends
            if hi >= 1.0:
                g_hi = g_new[e]
            else:
                dense_output(x, h, k, hi, x_try)
                g_hi = event_values(x_try, robot, p, config, volts, g_try)[e]
            if lo <= 0.0:
                g_lo = g_old[e]
            else:
                dense_output(x, h, k, lo, x_try)
                g_lo = event_values(x_try, robot, p, config, volts, g_try)[e]
            if g_hi >= 0.0:
                continue  # a root the polynomial has and the rounding of g does not
            if g_lo < 0.0:
                lo, g_lo = 0.0, g_old[e]
        else:
            g_lo, g_hi = bracket[2], bracket[3]
        brackets[0, e], brackets[1, e], brackets[2, e], brackets[3, e] = lo, hi, g_lo, g_hi
        triggered[e] = True
        any_event = True
    return any_event


@njit(**JIT_BORROW)
def initial_step(x, f0, robot, p, config, volts, scale, y1, f1):
    """Hairer's starting step, as scipy's select_initial_step (order 5); scale, y1 and f1
    are work vectors of the state's size.
    """
    n = x.shape[0]
    rtol, atol, weights = config.rtol, config.atol, config.tolerance_weights
    for i in range(n):
        scale[i] = (atol + rtol * abs(x[i])) * weights[i]
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
        applied_voltages(x, robot, p, config, volts)
        sample = samples[n]
        sample.t = t
        for i in range(x.shape[0]):  # element by element: a slice assignment of record arrays needs NRT
            sample.x[i] = x[i]
        for i in range(3):
            sample.voltage[i] = volts[i]
        robot.n_samples = n + 1


WORK_SHAPE = (18, N_STATE)       # float64: stages, stage and trial states, scales, dense coefficients
SMALL_SHAPE = (9, N_EVENTS)      # float64: event values, voltages, brackets
STACK_SHAPE = (STACK_DEPTH, 7)   # float64: the in-step searches' intervals


@njit(**JIT)
def new_workspace():
    """The fixed-size work arrays of integrate_with (on a GPU: local arrays of these shapes)."""
    return (np.empty(WORK_SHAPE), np.empty(SMALL_SHAPE), np.empty(STACK_SHAPE),
            np.zeros(N_EVENTS, dtype=np.bool_))


@njit(**JIT)
def integrate(robot, p, config, t_end, log, samples):
    """Advance the robot (in place) from robot.t to t_end or to the first stop event.

    The robot's hybrid modes are in/out (fill them with initial_modes once per
    simulation), and so is its step size, so that consecutive calls keep it. samples:
    a SAMPLE array, or None to record nothing. Returns the status; robot.t is the time
    reached.
    """
    return integrate_with(robot, p, config, t_end, log, samples, new_workspace())


@njit(**JIT_BORROW)
def integrate_with(robot, p, config, t_end, log, samples, workspace):
    """integrate() in the given work arrays (new_workspace): it allocates nothing and assigns
    no slices, so that numba-cuda compiles it as a device function.
    """
    return integrate_timed(robot, p, config, t_end, log, samples, workspace, None)


@intrinsic
def cycles(typingctx):
    """The CPU's cycle counter (llvm.readcyclecounter: rdtsc on x86), for the cost breakdown."""
    def codegen(context, builder, signature, args):
        counter = cgutils.get_or_insert_function(builder.module, llvm_ir.FunctionType(llvm_ir.IntType(64), []),
                                                 "llvm.readcyclecounter")
        return builder.call(counter, [])
    return types.int64(), codegen


# slots of the timers of integrate_timed [cycles]: the switch search (event values at the step's
# end and the search inside it) and the event location (the root refinement, the mode switches
# and the restart's bookkeeping, without its right-hand side)
T_SEARCH, T_LOCATE = 0, 1
N_TIMERS = 4  # the environment step adds its total (envs.core.T_STEP)


@njit(**JIT_BORROW)
def integrate_timed(robot, p, config, t_end, log, samples, workspace, timers):
    """integrate_with, and with timers (an int64 array, not None) the cycles spent in the
    parts named by T_SEARCH and T_LOCATE added to it. With timers None numba prunes every
    timer branch before compiling: integrate_with's machine code has no trace of them.
    """
    n = N_STATE
    work, small, stack, triggered = workspace
    k = work[:7]
    y_new = work[7]
    y_stage = work[8]
    x_event = work[9]
    scale = work[10]
    err_vec = work[11]
    coeffs = work[12:16]
    reach = work[16]
    bend = work[17]
    g_old = small[0]
    g_new = small[1]
    g_try = small[2]
    volts = small[3, :3]
    brackets = small[4:8]  # per event: lo, hi, g(lo), g(hi) in theta
    bracket = small[8, :4]  # the searches' result
    x = robot.x
    rtol, atol = config.rtol, config.atol
    weights = config.tolerance_weights

    t = robot.t
    settle_saturation(x, robot, p, config)
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
            scale[i] = (atol + rtol * max(abs(x[i]), abs(y_new[i]))) * weights[i]
        err = rms_norm(err_vec, scale)
        finite = math.isfinite(err)
        if not finite or err > 1.0:  # rejected: a non-finite state shrinks the step tenfold
            h = h_step * max(MIN_FACTOR, SAFETY * err ** -0.2) if finite else 0.1 * h_step
            robot.n_rejected += 1
            if h < 1e-14 * max(1.0, abs(t)):
                robot.step_size = h
                robot.t = t
                return STATUS_STEP_UNDERFLOW if finite else STATUS_NOT_FINITE
            continue
        robot.n_steps += 1
        factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** -0.2)

        if timers is not None:
            started = cycles()
        event_values(y_new, robot, p, config, volts, g_new)
        if config.exact_switches:
            any_event = search_switches(x, y_new, h_step, k, robot, p, config, volts, g_old, g_new, g_try,
                                        x_event, coeffs, reach, bend, stack, bracket, brackets, triggered)
        else:  # sign changes at the step's ends only
            any_event = False
            for e in range(N_EVENTS):
                triggered[e] = g_old[e] >= 0.0 and g_new[e] < 0.0
                if triggered[e]:
                    any_event = True
                    brackets[0, e], brackets[1, e], brackets[2, e], brackets[3, e] = 0.0, 1.0, g_old[e], g_new[e]
        if timers is not None:
            searched = cycles()
            timers[T_SEARCH] += searched - started
        if not any_event:
            t = t_end if last else t + h_step
            for i in range(n):
                x[i] = y_new[i]
                k[0, i] = k[6, i]
            for e in range(N_EVENTS):
                g_old[e] = g_new[e]
            h = max(h, h_step * factor) if last else h_step * factor
            if samples is not None:
                record(t, x, robot, p, config, volts, samples)
            continue

        # locate the earliest event on the dense output (Illinois), bracket [lo, hi] in theta
        theta_first = 1.0
        for e in range(N_EVENTS):
            if not triggered[e]:
                continue
            lo, hi, g_lo, g_hi = brackets[0, e], brackets[1, e], brackets[2, e], brackets[3, e]
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
            for i in range(n):
                x_event[i] = y_new[i]
        else:
            dense_output(x, h_step, k, theta_first, x_event)
        event_values(x_event, robot, p, config, volts, g_try)
        t = t_end if (last and theta_first >= 1.0) else t + theta_first * h_step
        for i in range(n):
            x[i] = x_event[i]
        stop = False
        for e in range(N_EVENTS):
            if triggered[e] and g_try[e] < 0.0:
                stop = handle_event(e, t, x, robot, p, config, log) or stop
        settle_saturation(x, robot, p, config)  # the critical switch moves the PD law's bounds
        settle_holds(t, x, robot, p, config, volts, log)
        if samples is not None:
            record(t, x, robot, p, config, volts, samples)
        if timers is not None:
            restarted = cycles()
        derivative(x, robot, p, config, k[0], volts)
        robot.n_rhs += 1
        if timers is not None:
            timers[T_LOCATE] += restarted - searched
            located = cycles()
        event_values(x, robot, p, config, volts, g_old)
        h = h_step  # the step up to the event was accurate; keep its size
        if timers is not None:
            timers[T_LOCATE] += cycles() - located
        if stop:
            robot.step_size = h
            robot.t = t
            return STATUS_STOPPED
    robot.step_size = h
    robot.t = t
    return STATUS_END


@njit(**JIT)
def rhs_cycles(states, robot, p, config, repeats):
    """Cycles per right-hand side on the given states (rows), in the robot's modes: the unit
    of the benchmark's cost breakdown. Returns (cycles, a checksum that keeps the loop).
    """
    out = np.empty(N_STATE)
    volts = np.empty(3)
    checksum = 0.0
    started = cycles()
    for _ in range(repeats):
        for row in range(states.shape[0]):
            derivative(states[row], robot, p, config, out, volts)
            checksum += out[RATE]
    return (cycles() - started) / (repeats * states.shape[0]), checksum


# entry points for Python callers: one-element record arrays dispatch faster than records
@njit(**JIT)
def advance(robots, params, configs, t_end, log, samples):
    """integrate() on element 0 of the record arrays; samples may be None."""
    return integrate(robots[0], params[0], configs[0], t_end, log, samples)


@njit(**JIT)
def start(robots, params, configs):
    """initial_modes() on element 0 of the record arrays."""
    initial_modes(robots[0], params[0], configs[0])
