"""scara_gym.benchmark.bench: the figures it computes are well defined (speed itself is reported, not tested)."""

from scara_gym.benchmark.bench import bench_warp_bound


def test_the_warp_bound_is_a_fraction_of_the_busiest_robots_work():
    bound = bench_warp_bound("pd", n=64, steps=8)
    assert 0.0 < bound["efficiency"] < 1.0  # robots differ in their integrator work
    assert 0.0 < bound["sorted_efficiency"] <= 1.0
    assert 0 < bound["mean_work"] < bound["largest_work"]
    one_warp_per_robot = bench_warp_bound("pd", n=64, steps=8, warp=1)
    assert one_warp_per_robot["efficiency"] == 1.0 and one_warp_per_robot["mean_work"] == bound["mean_work"]
