"""Task c against the spec's independent reference table."""

import numpy as np
import pytest

from scara_gym.benchmark.tasks import obstacle_avoidance
from scara_gym.model.params import DEFAULT_PARAMS

MS = 5e-4  # the spec's reference is given to 0.5 ms

# case: (critical from, q3 reaches h_obs, target reached)  (shared/c11-spec.md, task c)
SPEC = {
    ("restart", 5e-5): (0.3492, 0.5273, 1.4560),
    ("continuous", 5e-5): (0.3492, 0.5273, 1.4367),
    ("restart", 5e-3): (0.3492, 0.5273, 1.4543),
    ("continuous", 5e-3): (0.3492, 0.5273, 1.4350),
}


@pytest.mark.parametrize("variant, dec", list(SPEC))
def test_task_c_reproduces_the_spec_reference(variant, dec):
    critical, above, reached = SPEC[(variant, dec)]
    run = obstacle_avoidance(variant=variant, dec=dec)
    assert run.first("critical_on") == pytest.approx(critical, abs=MS)
    assert run.first("above_wall") == pytest.approx(above, abs=MS)
    assert run.reach_time == pytest.approx(reached, abs=MS)
    assert run.collision_time is None
    assert run.times("wall_cross")  # it did pass the wall, above it
    tip = run.tip
    below = run.q[:, 2] < DEFAULT_PARAMS.obstacle.height
    side = np.sign(tip[:, 0] - DEFAULT_PARAMS.obstacle.x_position)
    assert np.all(side[below] >= 0)  # never beyond the wall while below its height


def test_plain_pd_collides_at_about_0_36_s():
    run = obstacle_avoidance(variant="none")
    assert run.collision_time == pytest.approx(0.36, abs=5e-3)
    assert run.first("critical_on") is None
    stopped = obstacle_avoidance(variant="none", stop_on_collision=True)
    assert stopped.status == "collision" and stopped.end_time == pytest.approx(run.collision_time, abs=1e-12)


def test_restart_variant_resets_rates_and_currents_and_continuous_does_not():
    restart = obstacle_avoidance(variant="restart")
    above = restart.first("above_wall")
    after = np.flatnonzero(restart.t == above)
    assert len(after) >= 2  # end of the climb, start of the restart
    assert np.any(restart.x[after[0], 3:9] != 0)
    assert np.all(restart.x[after[-1], 3:9] == 0)
    assert restart.energy[after[-1]] == restart.energy[after[0]] > 0  # the accumulator runs on
    continuous = obstacle_avoidance(variant="continuous")
    i = np.searchsorted(continuous.t, continuous.first("critical_off"))
    assert np.abs(continuous.rates[i, :2]).max() > 1.0  # rates built up during the freeze carry over


def test_dec_rule_freezes_the_tip_while_critical():
    run = obstacle_avoidance(variant="continuous", dec=5e-5)
    start, end = run.first("critical_on"), run.first("critical_off")
    inside = (run.t >= start) & (run.t <= end)
    tip = run.tip[inside]
    # |d tip/dt| <= dec (L1 + L2)(|v1| + |v2|): the frozen tip creeps by dec times the free motion
    bound = 5e-5 * 0.7 * np.abs(run.rates[inside, :2]).sum(axis=1).max() * (end - start)
    assert 0 < np.hypot(np.ptp(tip[:, 0]), np.ptp(tip[:, 1])) <= bound
    assert bound < 1e-4
    assert run.q[inside, 2][-1] == pytest.approx(0.15) and np.ptp(run.q[inside, 2]) > 0.05  # q3 climbs
    # the widened voltage is used while critical
    assert np.abs(run.voltage[inside, 2]).max() > DEFAULT_PARAMS.axes[2].voltage_limit


def test_obstacle_parameters_are_parameters():
    high = DEFAULT_PARAMS.replace({"obstacle.height": 0.25})
    run = obstacle_avoidance(high, variant="continuous")
    assert run.first("above_wall") > 0.6 and run.collision_time is None
    assert run.reach_time > obstacle_avoidance(variant="continuous").reach_time


@pytest.mark.parametrize("kwargs, error, words", [
    (dict(variant="matlab"), ValueError, "variant must be one of"),
    (dict(dec=0.0), ValueError, "ObstacleParams.dec"),
    (dict(dec=float("nan")), ValueError, "ObstacleParams.dec"),
    (dict(form="inverse"), ValueError, "form must be one of"),
])
def test_bad_task_c_input(kwargs, error, words):
    with pytest.raises(error, match=words):
        obstacle_avoidance(**kwargs)
