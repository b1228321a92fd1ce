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

from scara_gym import layout as L
from scara_gym.dynamics import derivative
from scara_gym.integrator import event_values, handle_event, initial_modes, settle_holds
from scara_gym.params import DEFAULT_PARAMS, ScaraParams
from scara_gym.simulation import FORMS, check_tolerance, start_state

_TRACKED = (L.E_HOLD1, L.E_HOLD2, L.E_HOLD3, L.E_TARGET)


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
        raise ValueError(f"form must be one of {sorted(FORMS)}, got {form!r}")
    p = params.to_array()
    command = np.array(params.task.target)
    config = np.zeros(L.N_CONFIG, dtype=np.int64)
    config[L.C_FORM] = FORMS[form]
    config[L.C_STOP] = L.STOP_TARGET
    modes = np.zeros(L.N_MODES, dtype=np.int64)
    ev_t = np.empty(64)
    ev_code = np.empty(64, dtype=np.int64)
    ev_axis = np.empty(64, dtype=np.int64)
    counters = np.zeros(L.N_COUNTERS, dtype=np.int64)
    volts = np.empty(3)
    g = np.empty(L.N_EVENTS)
    x = start_state(params)
    initial_modes(x, p, command, config, modes)

    def rhs(_t, y):
        return derivative(y, p, command, config, modes, np.empty(L.N_STATE), volts)

    def make_event(k):
        def event(_t, y):
            return event_values(y, p, command, config, modes, volts, g)[k]
        event.terminal = True
        event.direction = -1
        return event

    events = [make_event(k) for k in _TRACKED]
    started = time.perf_counter()
    t = 0.0
    segments = []
    reach_time = None
    while t < t_end and reach_time is None:
        settle_holds(t, x, p, command, config, modes, volts, ev_t, ev_code, ev_axis, counters)
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
        if handle_event(_TRACKED[which], t, x, p, config, modes, ev_t, ev_code, ev_axis, counters):
            reach_time = t
    return reach_time, segments, time.perf_counter() - started
