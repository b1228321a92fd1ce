"""Index layout of the flat arrays the compiled core works on.

Module-level integers, so that numba folds them into constants.
"""

# state vector x
Q1, Q2, Q3 = 0, 1, 2            # joint angles [rad], height [m]
V1, V2, V3 = 3, 4, 5            # rate states [rad/s, rad/s, m/s]
I1, I2, I3 = 6, 7, 8            # armature currents [A]
ENERGY = 9                      # electrical energy drawn since the start, int sum U_i I_i dt [J]
N_STATE = 10                    # an accumulator, integrated with the state so it is exact

# parameter vector p (ScaraParams.to_array)
TH1, TH2, TH3, MA33, M3L, GRAVITY, L1, L2 = 0, 1, 2, 3, 4, 5, 6, 7
AXIS0 = 8
AXIS_STRIDE = 9
A_R, A_L, A_KT, A_GEAR, A_IMAX, A_P, A_D, A_UMAX, A_UWIDE = range(9)
X_OBS = AXIS0 + 3 * AXIS_STRIDE  # 35
D_CRIT = X_OBS + 1
H_OBS = X_OBS + 2
DEC = X_OBS + 3
TARGET = X_OBS + 4               # 3 entries
ACC = TARGET + 3
N_PARAMS = ACC + 1

# integer configuration of one simulation (config vector)
C_FORM = 0        # FORM_EXPLICIT or FORM_IMPLICIT
C_CONTROL = 1     # CONTROL_PD (command = set-point) or CONTROL_VOLTAGE (command = U/limit)
C_CRITICAL = 2    # CRIT_OFF, CRIT_SWITCH (evaluated at every instant), CRIT_FORCED
C_WIDEN = 3       # 1: voltage limit Umax_wide while critical
C_DEC = 4         # 1: q1' = dec v1, q2' = dec v2 while critical
C_STOP = 5        # bit mask of STOP_*
C_WALL = 6        # 1: track crossings of the wall plane (collisions)
C_MAX_STEPS = 7   # accepted + rejected step budget of one call
N_CONFIG = 8

FORM_EXPLICIT, FORM_IMPLICIT = 0, 1
CONTROL_PD, CONTROL_VOLTAGE = 0, 1
CRIT_OFF, CRIT_SWITCH, CRIT_FORCED = 0, 1, 2

STOP_TARGET = 1       # entered the target band
STOP_COLLISION = 2    # crossed the wall plane below h_obs
STOP_CRITICAL = 4     # became critical
STOP_ABOVE = 8        # q3 rose to h_obs

# hybrid mode vector (persists across calls)
M_HOLD1, M_HOLD2, M_HOLD3 = 0, 1, 2   # -1 / 0 / +1: current held at -Imax, free, held at +Imax
M_CRITICAL = 3                        # 0/1
M_SIDE = 4                            # sign of x_tip - x_obs
M_ABOVE = 5                           # 1 while q3 >= h_obs
M_INSIDE = 6                          # 1 while all |q_i - q^_i| < acc
N_MODES = 7

# event functions (index into the g vector; positive while the mode holds)
E_HOLD1, E_HOLD2, E_HOLD3, E_CRITICAL, E_SIDE, E_HEIGHT, E_TARGET = range(7)
N_EVENTS = 7

# codes written to the event log
EV_LIMIT_ON = 1       # axis = 0..2; current reached +-Imax and is held
EV_LIMIT_OFF = 2
EV_CRITICAL_ON = 3
EV_CRITICAL_OFF = 4
EV_WALL_CROSS = 5     # crossed the wall plane above h_obs: harmless
EV_COLLISION = 6      # crossed the wall plane below h_obs
EV_ABOVE = 7          # q3 reached h_obs
EV_BELOW = 8
EV_TARGET_IN = 9
EV_TARGET_OUT = 10
EVENT_NAMES = {
    EV_LIMIT_ON: "current_limit_on", EV_LIMIT_OFF: "current_limit_off",
    EV_CRITICAL_ON: "critical_on", EV_CRITICAL_OFF: "critical_off",
    EV_WALL_CROSS: "wall_cross", EV_COLLISION: "collision",
    EV_ABOVE: "above_wall", EV_BELOW: "below_wall",
    EV_TARGET_IN: "target_reached", EV_TARGET_OUT: "target_left",
}

# counters vector
K_RECORDS, K_EVENTS, K_RHS, K_STEPS, K_REJECTED, K_LAST_EVENT = range(6)
N_COUNTERS = 6

# return status of integrate()
STATUS_END = 0          # reached t_end
STATUS_STOPPED = 1      # a stop event fired (counters[K_LAST_EVENT])
STATUS_MAX_STEPS = -1
STATUS_STEP_UNDERFLOW = -2
STATUS_NOT_FINITE = -3
