"""Task b with scipy's ``solve_ivp``: an independent integrator for checks and benchmarks.

Same model functions, same hybrid modes and event functions as the compiled
integrator, but scipy's steppers, step control and event location. The tests use
it at tight tolerance (DOP853) as the reference for the compiled integrator; the
benchmark runs it at the compiled integrator's tolerances (RK45, LSODA).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.integrate import solve_ivp

from scara_gym.model import records as R
from scara_gym.model.checks import UserError
from scara_gym.model.dynamics import derivative
from scara_gym.model.integrator import event_values, handle_event, initial_modes, settle_holds
from scara_gym.model.params import DEFAULT_PARAMS, ScaraParams
from scara_gym.model.simulator import FORMS, check_tolerance, start_state

_TRACKED = (R.E_HOLD1, R.E_HOLD2, R.E_HOLD3, R.E_TARGET)


def scipy_point_to_point(params: ScaraParams = DEFAULT_PARAMS, *, method: str = "RK45",
                         rtol: float = 1e-10, atol: float = 1e-12, form: str = "explicit",
                         t_end: float = 5.0, dense: bool = False):
    """Run task b with solve_ivp, segment by segment between mode switches.

    Returns (reach_time, segments, runtime) where segments are solve_ivp results
    (with dense output if ``dense``).
    """
    check_tolerance("rtol", rtol)
    check_tolerance("atol", atol)
    if form not in FORMS:
        raise UserError(f"form must be one of {sorted(FORMS)}, got {form!r}")
    p = params.to_record()
    config = np.zeros(1, dtype=R.CONFIG)[0]
    config["form"] = FORMS[form]
    config["stops"] = R.STOP_TARGET
    robot = np.zeros(1, dtype=R.ROBOT)[0]
    robot["x"] = start_state(params)
    robot["command"] = params.task.target
    log = np.zeros(64, dtype=R.EVENT)
    volts = np.empty(3)
    g = np.empty(R.N_EVENTS)
    initial_modes(robot, p, config)

    def rhs(_t, y):
        return derivative(y, robot, p, config, np.empty(R.N_STATE), volts)

    def make_event(k):
        def event(_t, y):
            return event_values(y, robot, p, config, volts, g)[k]
        event.terminal = True
        event.direction = -1
        return event

    events = [make_event(k) for k in _TRACKED]
    started = time.perf_counter()
    t = 0.0
    x = robot["x"].copy()
    segments = []
    reach_time = None
    while t < t_end and reach_time is None:
        settle_holds(t, x, robot, p, config, volts, log)
        sol = solve_ivp(rhs, (t, t_end), x, method=method, rtol=rtol, atol=atol,
                        events=events, dense_output=dense)
        segments.append(sol)
        if sol.status == -1:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        if sol.status == 0:
            break
        hits = [(times[0], i) for i, times in enumerate(sol.t_events) if len(times)]
        t, which = min(hits)
        x = sol.y_events[which][0].copy()
        if handle_event(_TRACKED[which], t, x, robot, p, config, log):
            reach_time = t
    return reach_time, segments, time.perf_counter() - started
