"""scara_gym.benchmark.bench: the figures it computes are well defined (speed itself is reported, not tested)."""

import pytest

from scara_gym.benchmark.bench import COST_PARTS, bench_cost, bench_warp_bound


def test_the_warp_bound_is_a_fraction_of_the_busiest_robots_work():
    bound = bench_warp_bound("pd", n=64, steps=8)
    assert 0.0 < bound["efficiency"] < 1.0  # robots differ in their integrator work
    assert 0.0 < bound["sorted_efficiency"] <= 1.0
    assert 0 < bound["mean_work"] < bound["largest_work"]
    one_warp_per_robot = bench_warp_bound("pd", n=64, steps=8, warp=1)
    assert one_warp_per_robot["efficiency"] == 1.0 and one_warp_per_robot["mean_work"] == bound["mean_work"]


def test_the_cost_breakdown_splits_each_ids_step_into_its_parts():
    rows = bench_cost(("Scara-C11-v0", "Scara-C11-v2"), steps=60, rounds=1)
    assert [row["env_id"] for row in rows] == ["Scara-C11-v0", "Scara-C11-v2"]
    for row in rows:
        assert row["total"] == pytest.approx(sum(row[part] for part in COST_PARTS))
        assert row["total"] == pytest.approx(1e6 / row["steps_per_second"])
        assert min(row["rhs"], row["search"], row["locate"]) > 0.0
        # six right-hand sides per Dormand-Prince step, one more at each start and restart
        assert row["rhs_per_step"] > 6 * row["steps_per_step"] > 0
    v0, v2 = rows
    assert v2["rhs_per_step"] > v0["rhs_per_step"]  # tighter tolerances: more right-hand sides
