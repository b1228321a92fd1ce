"""The compiled hybrid integrator against scipy at tight tolerance, and task b."""

import numpy as np
import pytest

from scara_gym.benchmark.reference import scipy_point_to_point
from scara_gym.benchmark.tasks import compare_forms, point_to_point, sample_point_to_point
from scara_gym.model.params import DEFAULT_PARAMS
from scara_gym.model.simulator import SimulationError, Simulator, start_state

SPEC_TASK_B = 1.5703


@pytest.fixture(scope="module")
def task_b():
    return point_to_point()


def test_task_b_stop_event(task_b):
    assert task_b.status == "target"
    assert task_b.reach_time == pytest.approx(SPEC_TASK_B, abs=2e-4)
    assert task_b.end_time == task_b.reach_time
    final_error = np.abs(task_b.q[-1] - np.array([2.0, 2.0, 0.3])).max()
    assert final_error == pytest.approx(1e-3, abs=1e-9)  # located on the band's edge


def test_axes_1_and_2_reach_their_current_limits_and_never_exceed_them(task_b):
    limits = np.array([6.64, 2.771, 1.732])
    peak = np.abs(task_b.currents).max(axis=0)
    assert np.all(peak <= limits * (1 + 1e-12))
    assert peak[0] == pytest.approx(limits[0], rel=1e-12)
    assert peak[1] == pytest.approx(limits[1], rel=1e-12)
    assert peak[2] < 0.99 * limits[2]
    limited_axes = {e.axis for e in task_b.events if e.kind == "current_limit_on"}
    assert limited_axes == {0, 1}


def test_matches_scipy_dop853_at_tight_tolerance(task_b):
    reach, segments, _ = scipy_point_to_point(method="DOP853", rtol=1e-12, atol=1e-14, dense=True)
    assert reach == pytest.approx(task_b.reach_time, abs=1e-9)
    times = np.linspace(0.0, reach, 300)
    ours = sample_point_to_point(times, rtol=1e-11, atol=1e-13)
    for t, x in zip(times, ours):
        segment = next(s for s in segments if s.t[0] <= t <= s.t[-1])
        ref = segment.sol(t)
        assert np.allclose(x, ref, rtol=1e-7, atol=1e-8), (t, x - ref)


def test_loose_tolerance_stays_close():
    loose = point_to_point(rtol=1e-6, atol=1e-9)
    assert loose.reach_time == pytest.approx(SPEC_TASK_B, abs=2e-4)
    assert loose.reach_time == pytest.approx(point_to_point().reach_time, abs=1e-6)


def _task_b_with(**kwargs) -> Simulator:
    sim = Simulator(stop=("target",), record=0, exact_switches=True, **kwargs)
    sim.reset(start_state(DEFAULT_PARAMS), command=DEFAULT_PARAMS.task.target)
    assert sim.status_name(sim.advance(3.0)) == "target"
    return sim


def test_tolerance_weights_scale_each_groups_tolerances(task_b):
    plain = _task_b_with(rtol=1e-7, atol=1e-9)
    ones = _task_b_with(rtol=1e-7, atol=1e-9, tolerance_weights={"q": 1.0, "rate": 1.0, "current": 1.0})
    assert np.array_equal(ones.x, plain.x) and ones.robot["n_rhs"] == plain.robot["n_rhs"]
    # the currents dominate the error estimate: loosening theirs alone saves steps, tightening q costs some
    loose_currents = _task_b_with(rtol=1e-7, atol=1e-9, tolerance_weights={"current": 30.0})
    tight_q = _task_b_with(rtol=1e-7, atol=1e-9, tolerance_weights={"q": 0.01})
    assert loose_currents.robot["n_rhs"] < plain.robot["n_rhs"] < tight_q.robot["n_rhs"]
    reference = task_b.reach_time
    for sim in (plain, loose_currents, tight_q):
        assert sim.robot["t"] == pytest.approx(reference, abs=1e-6)
    # a weight applies to its group only: even a large energy weight leaves the motion within 1e-6
    energy = _task_b_with(rtol=1e-7, atol=1e-9, tolerance_weights={"energy": 1000.0})
    assert np.abs(energy.x[:9] - plain.x[:9]).max() < 1e-6


def test_implicit_and_explicit_forms_agree():
    result = compare_forms(repeats=1)
    assert result.max_relative_difference < 1e-8
    assert result.reach_time_implicit == pytest.approx(result.reach_time_explicit, abs=1e-10)
    assert result.runtime_explicit > 0 and result.runtime_implicit > 0


def test_bad_input_is_rejected_with_a_clear_error():
    with pytest.raises(ValueError, match="form must be one of"):
        point_to_point(form="semi-implicit")
    with pytest.raises(ValueError, match="q0 must be 3 finite numbers"):
        point_to_point(q0=[0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match=r"rtol must be a finite number in \[1e-14, 0.01\]"):
        point_to_point(rtol=-1.0)


def test_an_exhausted_step_budget_names_its_cause():
    sim = Simulator(max_steps=50, record=0)
    sim.reset(start_state(DEFAULT_PARAMS), command=DEFAULT_PARAMS.task.target)
    with pytest.raises(SimulationError) as info:
        sim.advance(1.0)
    message = str(info.value)
    for words in ("max_steps = 50", "step size", "electrical time constant", "rtol = 1e-10", "raise max_steps"):
        assert words in message
    assert 0.0 < sim.t < 1.0  # stopped where the budget ran out, not at t_end
