"""The comparison command: every policy over the same seeds, rliable aggregates, the JSON format."""

import json

import numpy as np
import pytest

from scara_gym import LATEST_ENV_ID

pytest.importorskip("rliable")
pytest.importorskip("stable_baselines3")
from agents.algorithms.sb3 import hyperparams, training  # noqa: E402
from agents.experiments import (  # noqa: E402
    comparison,
    evaluation,
    registry,
    report,
    runs as run_folders,  # noqa: E402
    statistics,
)
from agents.experiments.targets import target_checks  # noqa: E402
from scara_gym.benchmark.protocol import CONDITIONS  # noqa: E402

HEURISTICS = {v: {"distance": 0.07, "margin_distance": 0.084} for v in ("continue", "restart")}
"""tuned distances for the tests (the real tuning runs in test_tuning)"""

KEYS = {"name", "kind", "algorithm", "seeds", "episodes", "success_rate", "collision_rate", "time_iqm",
        "time_ci", "energy_mean", "return_mean", "condition"}


def test_iqm_and_probability_of_improvement_on_known_scores():
    scores = np.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0], [100.0, 100.0]])
    iqm, (low, high) = statistics.iqm_with_ci(scores, reps=500)
    assert iqm == pytest.approx(2.5)  # the middle half of the 8 scores: 2, 2, 3, 3
    assert low <= iqm <= high
    faster, _ = statistics.probability_faster(np.full((3, 2), 1.0), np.full((1, 2), 2.0), reps=200)
    assert faster == 1.0
    tie, _ = statistics.probability_faster(np.full((3, 2), 2.0), np.full((1, 2), 2.0), reps=200)
    assert tie == 0.5


def test_the_iqm_is_rliables_to_the_last_bit():
    """statistics.iqm replaces rliable's aggregate_iqm inside the bootstrap: the same number, bit for
    bit (float64, float32 and integer scores, ties, every size from 1, NaN), so intervals do not move."""
    from rliable import metrics

    rng = np.random.default_rng(7)
    for k in range(2000):
        shape = (int(rng.integers(1, 9)), int(rng.integers(1, 40)))
        scores = [rng.normal(size=shape), rng.choice([3.0, 1.2, 1.25, 1.3], size=shape),
                  rng.integers(0, 5, size=shape), rng.uniform(1, 3, size=shape).astype(np.float32)][k % 4]
        if k % 97 == 0:
            scores = scores.astype(float)
            scores.flat[0] = np.nan
        expected, got = metrics.aggregate_iqm(scores), statistics.iqm(scores)
        assert np.asarray(got).dtype == np.asarray(expected).dtype, (k, scores.dtype)
        assert np.array_equal(got, expected, equal_nan=True), (k, got, expected)
    scores = rng.uniform(1, 3, (5, 30))
    point, interval = statistics.interval_estimates(
        {"x": scores}, lambda s: np.array([metrics.aggregate_iqm(s)]), 300, 0)
    assert statistics.iqm_with_ci(scores, reps=300) == (point["x"][0], [interval["x"][0, 0], interval["x"][1, 0]])


def test_the_vectorized_probability_of_improvement_is_rliables():
    from rliable import metrics

    rng = np.random.default_rng(4)
    for runs_x, runs_y in ((5, 1), (3, 4), (2, 2)):
        x = rng.integers(0, 4, (runs_x, 30)).astype(float)  # few values: ties on purpose
        y = rng.integers(0, 4, (runs_y, 30)).astype(float)
        assert statistics.probability_of_improvement(x, y) == pytest.approx(metrics.probability_of_improvement(x, y),
                                                                         abs=1e-12)
    same = rng.uniform(size=(3, 10))
    assert statistics.probability_of_improvement(same, same) == metrics.probability_of_improvement(same, same) == 0.5


def test_comparison_command_writes_every_policy(tmp_path):
    runs = tmp_path / "runs"
    hyper = hyperparams.load_hyperparams("td3")
    hyper.update(n_envs=1, learning_starts=50, buffer_size=500, eval_freq=100, eval_episodes=1, snapshot_freq=100)
    for seed in (0, 1):
        training.train("td3", runs / LATEST_ENV_ID / "pd" / "td3" / f"seed{seed}", seed=seed,
                       hyperparams=hyper, total_timesteps=200)
    from agents.algorithms.torch_ppo import Config, train as train_torch_ppo
    train_torch_ppo(Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16, seed=3,
                           out=str(runs / LATEST_ENV_ID / "pd" / "torch-ppo" / "seed3")))
    # what is committed (results/runs): the finished runs, model and history only
    published = tmp_path / "published"
    from agents.cli import run
    assert len(run(["campaign", "td3", "--seeds", "0", "1", "2", "--runs", str(runs),
                    "--publish", str(published)])) == 2  # seed 2 never ran
    run_folders.publish(runs / LATEST_ENV_ID / "pd" / "torch-ppo" / "seed3",
                      published / LATEST_ENV_ID / "pd" / "torch-ppo" / "seed3")
    files = {p.relative_to(published).as_posix() for p in published.rglob("*") if p.is_file()}
    assert f"{LATEST_ENV_ID}/pd/td3/seed1/eval/evaluations.npz" in files
    assert not any(part in ("tb", "snapshot", "checkpoints") for f in files for part in f.split("/")), files
    with pytest.raises(ValueError, match="not a finished run"):
        run_folders.publish(runs / LATEST_ENV_ID / "pd" / "td3" / "seed2", tmp_path / "nowhere")
    out = tmp_path / "results"
    entries, traces = comparison.compare(published, ["c11"], episodes=2, verbose=False, heuristics=HEURISTICS,
                                         shielded=("torch-ppo",))
    names = [e["name"] for e in entries]
    assert names[:2] == ["pd", "pd + shield"] and "optimal" in names and "mpc" in names
    assert names[-3:] == ["td3", "torch-ppo", "torch-ppo + shield"]
    assert entries[-1]["seeds"] == [3] and entries[-1]["kind"] == "learned"
    assert entries[-1]["algorithm"] == "torch-ppo + shield" and entries[-1]["collision_rate"] == 0.0
    shielded_pd = entries[1]  # the shield alone takes PD past the wall
    assert shielded_pd["success_rate"] == 1.0 and shielded_pd["collision_rate"] == 0.0
    assert sum(e["kind"] == "heuristic" for e in entries) == 4  # two variants, tuned and with the margin
    for e in entries:  # the C11 condition is one episode, whatever --episodes says
        assert KEYS <= set(e) and e["condition"] == "c11" and e["episodes"] == 1
        assert e["time_ci"][0] <= e["time_iqm"] <= e["time_ci"][1]
        assert e["env_id"] == LATEST_ENV_ID  # every entry names the id it was scored on
        t = e["decision_time"]  # every row's compute per decision: the MPC's its solves', the others timed
        assert 0.0 < t["median"] <= t["p95"] and t["timed"] == ("solve" if e["kind"] in ("mpc", "mpc-rti") else "decision")
        assert t["decisions"] > 0  # the episode's control steps (PD's ends at its collision)
    pd, optimal, td3 = entries[0], entries[names.index("optimal")], entries[names.index("td3")]
    assert pd["collision_rate"] == 1.0 and pd["time_iqm"] == statistics.TIME_LIMIT
    assert optimal["success_rate"] == 1.0 and optimal["collision_rate"] == 0.0 and optimal["time_iqm"] < 1.25
    heuristic = [e for e in entries if e["kind"] == "heuristic"]
    assert all(e["success_rate"] == 1.0 and e["collision_rate"] == 0.0 for e in heuristic)
    assert td3["seeds"] == [0, 1] and [s["seed"] for s in td3["per_seed"]] == [0, 1]
    assert 0.0 <= td3["probability_faster_than_heuristic"] <= 1.0
    written = report.comparison_figures(entries, traces, evaluation.learned_runs(published), out.mkdir() or out)
    assert {p.name for p in written} == {"comparison_tip_paths.png", "comparison_time_energy.png",
                                        "comparison_learning_curves.png"}
    table = report.comparison_markdown(entries)
    assert "| optimal | optimal | voltage |" in table and "seed 1:" in table
    assert "| mpc | mpc | voltage |" in table and "mpc: solve time per control step median" in table
    assert "| mpc (pd) | mpc | pd |" in table and "mpc (pd): solve time per control step median" in table
    for name in ("mpc", "mpc (pd)"):
        mpc = entries[names.index(name)]
        assert mpc["success_rate"] == 1.0 and mpc["collision_rate"] == 0.0 and mpc["solve_time"]["solves"] > 100
    assert table.startswith("#### Targets") and "| optimal reference on the C11 target" in table
    assert f"Scored on `{LATEST_ENV_ID}`: 1 episode per policy and per training seed of a learned policy" in table
    assert "| decision, median / p95 (us) |" in table and " (solve) |" in table
    assert "| policy | c11 |\n" in table and "| pd | - (0.00 / 1.00) |\n" in table  # the overview
    assert f"| optimal | {optimal['time_iqm']:.3f} s |\n" in table
    json.dumps(entries)  # the JSON other tools read
    import shutil  # a run folder of a registered pilot is left out unless pilots=True
    shutil.copytree(published / LATEST_ENV_ID / "pd" / "torch-ppo",
                    published / LATEST_ENV_ID / "pd" / "torch-ppo-residual-frugal")
    assert "pilot" in registry.RUNS["torch-ppo-residual-frugal"].tags
    kwargs = dict(episodes=1, verbose=False, heuristics=HEURISTICS, shielded=(), include_optimal=False,
                  robust_shield=False, include_mpc=False)
    names = [e["name"] for e in comparison.compare(published, ["c11"], **kwargs)[0]]
    assert "torch-ppo-residual-frugal" not in names and "torch-ppo" in names
    names = [e["name"] for e in comparison.compare(published, ["c11"], pilots=True, **kwargs)[0]]
    assert "torch-ppo-residual-frugal" in names


def test_decision_time_is_the_wall_time_of_each_call_of_the_policy():
    """A policy that waits 2 ms per decision is timed at 2 ms or more at the median and the 95th
    percentile, once per control step of the condition's first episodes; PD is far faster."""
    import time

    from agents.policies import PDPolicy

    calls = []

    def slow_pd(env):
        pd = PDPolicy(env)

        def act(obs):
            calls.append(1)
            time.sleep(0.002)
            return pd(obs)
        return act

    condition = CONDITIONS["c11-starts"]
    slow = evaluation.decision_time(condition, slow_pd, "pd", episodes=2)
    assert slow["decisions"] == len(calls) > 10 and 0.002 <= slow["median"] <= slow["p95"]
    fast = evaluation.decision_time(condition, PDPolicy, "pd", episodes=2)
    assert fast["decisions"] == slow["decisions"] and fast["median"] < slow["median"] / 4


def test_networks_act_on_one_torch_thread_during_episodes_and_the_setting_is_given_back(monkeypatch):
    """Every evaluation path (a run's episodes, the evaluate command's rows, the decision timing)
    runs the policy's network on one torch thread and leaves torch's own setting as it found it,
    also when the episodes fail."""
    from pathlib import Path

    torch = pytest.importorskip("torch")
    from agents.policies import PDPolicy

    seen = []

    def torch_pd(env):  # a policy whose loader imported torch: it notes the threads it acts on
        pd = PDPolicy(env)

        def act(obs):
            seen.append(torch.get_num_threads())
            return pd(obs)
        act.name = "torch-pd"  # the evaluate command's row label
        return act

    # every loader of the module hands out that policy (a run folder or a spec named, none read)
    monkeypatch.setattr(evaluation, "run_spec", lambda run_dir, shield: "torch-pd")
    monkeypatch.setattr(evaluation, "load_policy", lambda spec, env: torch_pd(env))
    monkeypatch.setattr(evaluation, "make_policy", lambda spec, env: torch_pd(env))
    condition = CONDITIONS["c11-starts"]
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        paths = {"decision time": lambda: evaluation.decision_time(condition, torch_pd, "pd", episodes=1),
                 "a run's episodes": lambda: evaluation.learned_episodes(Path("a-run"), condition, "pd", 1),
                 "evaluate": lambda: evaluation.evaluate(["torch-pd"], "pd", "c11-starts", 1, record=0)}
        for path, run in paths.items():
            seen.clear()
            run()
            assert seen and set(seen) == {1} and torch.get_num_threads() == 2, path

        def broken(env):
            act = torch_pd(env)

            def fail(obs):
                act(obs)
                raise RuntimeError("the policy failed")
            return fail

        with pytest.raises(RuntimeError, match="the policy failed"), evaluation.OneTorchThread(broken) as factory:
            evaluation.evaluate_condition(condition, factory, "pd", 1)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)


def test_a_condition_without_a_shipped_optimal_solution_is_compared_without_it(monkeypatch, capsys):
    import agents.policies.optimal.policy

    monkeypatch.setattr(agents.policies.optimal.policy, "cached_solution", lambda *args, **kwargs: None)
    entries, _ = comparison.compare(None, ["c11"], episodes=2, verbose=True, heuristics=HEURISTICS, include_mpc=False)
    assert [e["kind"] for e in entries] == ["pd", "pd"] + ["heuristic"] * 4  # no solve of minutes inside
    assert "[c11] optimal: no shipped solution" in capsys.readouterr().out


@pytest.mark.parametrize("algo", ["torch-ppo-dr", "torch-ppo-residual-random", "torch-ppo-residual-frugal",
                                  "torch-ppo-residual-random-safe-fast", "torch-ppo-residual-fast-rsi",
                                  "torch-ppo-residual-random-replay"])
def test_the_campaign_trains_the_single_file_ppo_once(tmp_path, algo):
    out = tmp_path / algo / "seed0"
    run_folders.train_run(algo, out, seed=0, total_timesteps=2048)
    assert run_folders.is_finished(out)
    config = json.loads((out / "config.json").read_text())
    from agents.algorithms.torch_ppo import Config

    changed = {name: value for name, value in registry.RUNS[algo].fields.items() if name != "total_timesteps"}
    recorded = Config.from_dict(config)
    assert changed and {name: getattr(recorded, name) for name in changed} == changed
    assert config["global_step"] == 2048 and config["seed"] == 0
    summary = (out / "summary.json").read_text()
    run_folders.train_run(algo, out, seed=0, total_timesteps=2048, resume=True)  # finished: left as it is
    assert (out / "summary.json").read_text() == summary
    with pytest.raises(ValueError, match="holds this run already"):  # not resumed: refused, not retrained
        run_folders.train_run(algo, out, seed=0, total_timesteps=2048)
    with pytest.raises(ValueError, match="holds another run"):
        run_folders.train_run(algo, out, seed=1, total_timesteps=2048, resume=True)
    (out / "summary.json").unlink()  # model.pt is also a checkpoint: without the summary, not finished
    assert not run_folders.is_finished(out)


def _entry(condition, kind, algorithm=None, success=1.0, collisions=0.0, time=1.5, energy=70.0, seeds=None,
           train_seconds=600.0, mode="pd"):
    e = {"name": algorithm or kind, "kind": kind, "algorithm": algorithm, "condition": condition, "control_mode": mode,
         "success_rate": success, "collision_rate": collisions, "time_iqm": time, "energy_mean": energy,
         "run": algorithm, "shielded": False, "episodes": 30, "seeds": seeds,
         "tags": sorted(registry.RUNS[algorithm].tags) if algorithm in registry.RUNS else []}
    if seeds:
        e["per_seed"] = [{"seed": s, "success_rate": success, "collision_rate": collisions,
                          "train_seconds": train_seconds} for s in seeds]
    return e


def test_target_checks_say_met_or_the_number_reached():
    entries = [_entry("c11", "optimal", time=1.2241, energy=43.0),
               _entry("c11", "learned", "sac", time=1.20, energy=500.0, seeds=[0, 1], train_seconds=2000)]
    for condition in ("c11-starts", "random-targets"):  # runs trained on each condition's draws, and
        # a zero-shot one (trained on the C11 start alone), clean and fastest, that the targets leave out
        entries += [{**_entry(condition, "heuristic", time=1.60, energy=70.0), "name": "dec-continue, tuned (d=0.07 m)",
                     "variant": "continue", "setting": "tuned"},  # the fields the targets read, not the label
                    _entry(condition, "learned", "ppo", time=1.10, energy=60.0, seeds=[0, 1]),
                    _entry(condition, "learned", f"ppo-{condition}", time=1.34, energy=60.0, seeds=[0, 1]),
                    _entry(condition, "learned", f"sac-{condition}", success=0.5, time=1.20, energy=500.0, seeds=[0, 1])]
    entries[-2]["success_rate"] = 0.98  # ppo misses on random targets
    entries += [{**_entry("c11-starts", "pd", collisions=0.0), "name": "pd + shield", "shielded": True},
                {**_entry("delay-1", "pd", collisions=0.02), "name": "pd + shield", "shielded": True},
                {**_entry("load-x2", "pd", collisions=0.5), "name": "pd + shield", "shielded": True}]  # out of range
    entries += [_entry("sensor-noise", "learned", "ppo", success=0.96, seeds=[0])]
    checks = {c["target"].split(":")[0]: c for c in target_checks(entries)}
    assert checks["optimal reference on the C11 target"]["met"] is True
    shield = checks["shield"]
    assert shield["met"] is False and shield["reached"] == "pd + shield in delay-1: collisions 0.02"
    starts = checks["best learned without a shield, the C11 target from perturbed starts"]
    assert starts["met"] is True and starts["reached"].startswith("ppo-c11-starts:")  # sac is faster but fails seeds
    random = checks["best learned without a shield, randomized targets"]
    assert random["met"] is False and random["reached"].startswith("ppo-random-targets:")
    assert "success 0.98" in random["reached"]
    each = checks["each standard algorithm (no residual, no shield) trained on the c11-starts draws"]
    assert each["met"] is False and "ppo-c11-starts: success 1.00" in each["reached"]  # and sac's 0.50
    assert "sac-c11-starts: success 0.50" in each["reached"]
    best = checks["the best standard algorithm (no residual, no shield) trained on the random-targets draws"]
    assert best["met"] is True and best["reached"].startswith("ppo-random-targets: success 0.98")
    shifts = checks["the best standard algorithm (no residual, no shield) trained on the random-shifts draws"]
    assert shifts["met"] is None and "no standard run trained on the random-shifts draws" in shifts["reached"]
    assert checks["best learned without a shield under small sensor noise"]["met"] is True
    training_check = checks["each training run <= 30 min on 2 CPU cores"]
    assert training_check["met"] is False and "sac 33.3 min" in training_check["reached"]
    slow = target_checks([_entry("c11", "optimal", time=1.26)])
    assert slow[0]["met"] is False and "+3.13 %" in slow[0]["reached"]
    assert [c["met"] for c in slow[1:]] == [None] * (len(slow) - 1)


def test_the_mpc_targets_name_the_conditions_it_misses_and_its_solve_time_in_each_control_mode():
    from agents.experiments.targets import MPC_CLEAN

    timed = {"median": 0.004, "p95": 0.02, "worst": 0.05, "solves": 100, "failures": 0}

    def mpc(condition, mode, **kwargs):
        return {**_entry(condition, "mpc", mode=mode, **kwargs), "name": "mpc" if mode == "voltage" else "mpc (pd)",
                "solve_time": dict(timed)}

    entries = [_entry("c11", "optimal", time=1.2241, mode="voltage")]
    for mode in ("voltage", "pd"):
        entries += [mpc("c11", mode, time=1.25)] + [mpc(name, mode) for name in MPC_CLEAN]
    checks = {c["target"].split(":")[0]: c for c in target_checks(entries)}
    for mode in ("voltage", "pd"):
        near = checks[f"MPC ({mode} mode) on the C11 episode"]
        assert near["met"] is True and "+2.12 %" in near["reached"]
        clean = checks[f"MPC ({mode} mode) with its nominal model"]
        assert clean["met"] is True and f"{len(MPC_CLEAN)} of {len(MPC_CLEAN)}" in clean["reached"]
    assert checks["MPC"]["met"] is True and "4.0 ms" in checks["MPC"]["reached"]
    pd_rows = entries[1 + len(MPC_CLEAN) + 1:]
    pd_rows[0]["time_iqm"] = 1.27  # 3.7 % over the optimum, in "pd" mode only
    pd_rows[2]["collision_rate"] = 0.01
    entries[3]["solve_time"] = {**timed, "median": 0.012}
    checks = {c["target"].split(":")[0]: c for c in target_checks(entries)}
    assert checks["MPC (voltage mode) on the C11 episode"]["met"] is True
    assert checks["MPC (pd mode) on the C11 episode"]["met"] is False
    assert checks["MPC (voltage mode) with its nominal model"]["met"] is True
    clean = checks["MPC (pd mode) with its nominal model"]
    assert clean["met"] is False and clean["reached"] == f"{MPC_CLEAN[1]}: success 1.00, collisions 0.01"
    assert checks["MPC"]["met"] is False
    assert checks["MPC"]["reached"].startswith(f"slowest median: 12.0 ms (mpc, {MPC_CLEAN[1]}")
    missing = {c["target"].split(":")[0]: c for c in target_checks(entries[:2])}
    assert missing["MPC (voltage mode) with its nominal model"]["met"] is None
    assert "MPC (pd mode) with its nominal model" not in missing  # a mode nobody evaluated has no target


def test_a_cached_evaluation_is_reused_only_for_the_same_model_condition_and_episodes(tmp_path, monkeypatch):
    from agents.algorithms.torch_ppo import Config, train as train_torch_ppo

    run = tmp_path / "seed0"
    train_torch_ppo(Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16,
                           out=str(run)))
    c11, load = CONDITIONS["c11-starts"], CONDITIONS["load-x2"]
    cache = tmp_path / "cache"
    first = evaluation.learned_episodes(run, c11, "pd", 3, cache)
    assert len(list(cache.glob("*.npz"))) == 1 and not list(cache.glob("*.partial"))

    def must_not_run(*args, **kwargs):
        raise AssertionError("evaluated again")

    monkeypatch.setattr(evaluation, "evaluate_condition", must_not_run)
    again = evaluation.learned_episodes(run, c11, "pd", 3, cache)
    for key in ("success", "collisions", "reach_time", "energy", "trace"):
        assert np.array_equal(first[key], again[key], equal_nan=True), key
    assert len(again["traces"]) == 1 and np.array_equal(again["traces"][0], first["trace"])
    assert np.array_equal(again["seeds"], c11.seeds(3))
    key = evaluation.evaluation_key(run, c11, "pd", 3)
    assert key != evaluation.evaluation_key(run, load, "pd", 3)
    assert key != evaluation.evaluation_key(run, c11, "pd", 4)
    assert key != evaluation.evaluation_key(run, c11, "voltage", 3)
    assert key != evaluation.evaluation_key(run, c11, "pd", 3, shield=True)
    model = (run / "model.pt").read_bytes()
    (run / "model.pt").write_bytes(model + b"\0")  # another model: not the cached one
    from agents.files import POLICY_FILES, write_digests
    write_digests(run, POLICY_FILES)  # its own manifest, as a run that wrote it would have
    with pytest.raises(AssertionError, match="evaluated again"):
        evaluation.learned_episodes(run, c11, "pd", 3, cache)


def test_conditions_compared_in_parallel_give_the_sequential_entries():
    kwargs = dict(episodes=2, verbose=False, heuristics=HEURISTICS, include_optimal=False, include_mpc=False)
    sequential, _ = comparison.compare(None, ["c11", "wall-closer"], **kwargs)
    parallel, traces = comparison.compare_in_parallel(None, ["c11", "wall-closer"], 2, **kwargs)

    def untimed(entries):  # wall times differ from run to run; every other figure is the same
        assert all(e.pop("decision_time")["decisions"] > 0 for e in entries)
        return entries
    assert untimed(parallel) == untimed(sequential) and set(traces) == {"c11", "wall-closer"}


def test_the_corners_condition_is_scored_like_random_shifts_with_the_robust_shield_among_the_rows():
    """corners (issue 53) is one of the protocol's conditions, so the comparison's condition list holds
    it; its parameters vary, so PD behind the robust shield is scored there as in random-shifts. A
    condition without corners keeps its cache key."""
    entries, _ = comparison.compare(None, ["corners"], episodes=1, verbose=False, heuristics=HEURISTICS,
                                    include_optimal=False, include_mpc=False)
    assert {e["condition"] for e in entries} == {"corners"}
    assert {"pd", "pd + shield", comparison.ROBUST_LABEL} <= {e["name"] for e in entries}
    assert "corners" not in evaluation.condition_description(CONDITIONS["random-shifts"], 1)[0]
    assert evaluation.condition_description(CONDITIONS["corners"], 1)[0]["corners"] == "all"


def test_a_fine_tuned_variant_starts_from_its_base_run_and_counts_its_training_time(tmp_path):
    algo = "torch-ppo-residual-random-safe-fast"
    out = run_folders.run_dir(tmp_path, LATEST_ENV_ID, "pd", algo, 3)
    run_folders.train_run(algo, out, seed=3, total_timesteps=2048)
    base = run_folders.run_dir(tmp_path, LATEST_ENV_ID, "pd", registry.RUNS[algo].base, 3)
    assert run_folders.is_finished(base) and run_folders.is_finished(out)
    config, base_config = (json.loads((run / "config.json").read_text()) for run in (out, base))
    assert config["init_from"] == str(base) and base_config["seed"] == config["seed"] == 3
    assert base_config["reward_weights"] != config["reward_weights"]
    assert config["base_train_seconds"] == base_config["train_seconds"] > 0
    assert statistics.training_seconds(config) == config["train_seconds"] + base_config["train_seconds"]
    assert statistics.training_seconds(base_config) == base_config["train_seconds"]


def test_rates_keep_two_decimals_unless_that_hides_an_episode():
    assert [statistics.rate_text(r) for r in (1.0, 0.0, 0.57, 0.998, 0.002, 2 / 3)] == \
        ["1.00", "0.00", "0.57", "0.998", "0.002", "0.667"]


def test_verdicts_name_the_best_classical_and_learned_policy_and_the_winner():
    entries = [_entry("c11-starts", "pd", collisions=1.0, success=0.0, time=3.0),
               {**_entry("c11-starts", "heuristic", time=1.60, energy=70.0), "name": "dec-continue, tuned"},
               _entry("c11-starts", "learned", "ppo-c11-starts", time=1.40, energy=60.0, seeds=[0]),
               _entry("c11-starts", "learned", "sac-c11-starts", success=0.9, collisions=0.1, time=1.20, seeds=[0]),
               _entry("c11-starts", "learned", "torch-ppo", time=1.10, seeds=[0]),  # zero-shot: left out
               {**_entry("delay-1", "heuristic", success=0.2, collisions=0.8), "name": "dec-continue, tuned"},
               {**_entry("delay-1", "pd", time=1.5), "name": "pd + shield", "shielded": True},
               _entry("delay-1", "learned", "ppo", success=0.5, collisions=0.5, seeds=[0])]
    rows = report.verdicts(entries).splitlines()[4:]
    assert rows[0].startswith("| c11-starts | dec-continue, tuned: 1.00 / 0.00, 1.600 s")
    assert "| ppo-c11-starts: 1.00 / 0.00" in rows[0]
    assert rows[0].endswith("| learned wins: 0.200 s faster | - |")
    assert rows[1].startswith("| delay-1 | dec-continue, tuned:") and "learned wins: collisions 0.50 vs 0.80" in rows[1]
    assert rows[1].endswith("| pd + shield: 1.00 / 0.00, 1.500 s, 70 J; collisions 0 of 30 (at most 11.6 %) |")
    assert "| ppo: 0.50 / 0.50, 1.500 s, 70 J; collisions 15 of 30 (50.0 %, 95 % CI 31.3-68.7 %)" in rows[1]
    brief = report.verdict_summary(entries).splitlines()[2:]  # the README's: the same winners, in brief
    assert brief == ["| c11-starts | dec-continue, tuned (1.600 s) | ppo-c11-starts (1.400 s, 1 seed) | "
                     "learned: 0.200 s faster |",
                     "| delay-1 | dec-continue, tuned (1.500 s, 0.20 / 0.80) | ppo (1.500 s, 0.50 / 0.50, 1 seed) | "
                     "learned: collisions 0.50 vs 0.80, success 0.50 vs 0.20 |"]
    assert report.verdict_summary(entries, ("delay-1",)).splitlines()[2:] == brief[1:]


def test_robustness_curves_run_every_policy_at_every_point(tmp_path, monkeypatch):
    from agents.experiments import curves

    monkeypatch.setattr(curves, "CURVES", {"load mass": ("arm.load_mass", (1.0, 3.0)),
                                           "sensor noise": (None, (0.0, 5.0))})
    monkeypatch.setattr(curves, "tune_heuristic", lambda variant: {"distance": 0.07, "margin_distance": 0.084})
    data = curves.robustness_curves(None, episodes=2, verbose=False)
    assert set(data["curves"]) == {"load mass", "sensor noise"}
    for points in data["curves"].values():
        assert len(points["policies"]) == 3
        for row in points["policies"].values():
            assert len(row["success"]) == len(row["time_iqm"]) == 2 and all(0 <= s <= 1 for s in row["success"])
    shield = data["curves"]["load mass"]["policies"]["pd + shield"]
    assert shield["success"][0] == 1.0 and shield["collisions"][0] == 0.0  # nominal: the shield's own model
    written = curves.write_curves(data, tmp_path)
    assert all(p.exists() for p in written) and json.loads((tmp_path / "curves.json").read_text())["episodes"] == 2
    assert data["env_id"] == LATEST_ENV_ID


def test_the_curves_classical_points_come_back_from_the_cache(tmp_path, monkeypatch):
    """A stopped run of the curves goes on where it stopped: every classical point is kept."""
    from agents.experiments import curves

    monkeypatch.setattr(curves, "CURVES", {"load mass": ("arm.load_mass", (1.0, 2.0))})
    shielded = {"pd + shield": curves.shield_pd}
    first = curves.curve_points(shielded, {}, 1, cache=tmp_path, verbose=False)
    assert len(list(tmp_path.glob("curve-*.npz"))) == 2

    def must_not_run(*args, **kwargs):
        raise AssertionError("evaluated again")

    monkeypatch.setattr(curves, "evaluate", must_not_run)
    assert curves.curve_points(shielded, {}, 1, cache=tmp_path, verbose=False) == first


def test_the_report_says_what_budget_and_tuning_each_learned_row_had():
    entries = [{**_entry(c, "learned", "ppo-tuned-c11-starts", seeds=[0, 1]), "env_id": LATEST_ENV_ID}
               for c in ("c11-starts", "delay-1")]
    entries += [{**_entry("c11-starts", "learned", "sac", seeds=[0, 1, 2]), "env_id": LATEST_ENV_ID},
                {**_entry("c11-starts", "pd"), "env_id": LATEST_ENV_ID}]
    rows = report.learned_rows(entries).splitlines()[4:]
    assert len(rows) == 2  # one per run, not per condition; classical rows have none
    assert rows[0].startswith("| ppo-tuned-c11-starts | 0,1 | c11-starts draws | 10,000,000 steps |")
    assert rows[0].endswith("| searched: the best of its algorithm's hyperparameter search (record under results/search/) |")
    assert rows[1].startswith("| sac | 0,1,2 | the C11 episode's start | 60,000 steps |") and "untuned" in rows[1]


def test_a_zero_shot_cell_is_marked_in_the_tables_and_shows_no_numbers_in_the_headline():
    """A learned run scored in a training distribution whose draws it never trained on measures
    transfer: "zero-shot" beside its numbers in the full tables, alone in the headline."""
    entries = [_entry(condition, "learned", run, success=0.5, time=2.0, seeds=[0])
               for run in ("torch-ppo", "torch-ppo-residual-random-replay")
               for condition in ("c11", "random-targets", "sensor-noise")]
    full = report.overview(entries).splitlines()
    headline = report.overview(entries, hide_zero_shot=True).splitlines()
    assert full[4] == "| torch-ppo | 2.000 s (0.50 / 0.00) | 2.000 s (0.50 / 0.00), zero-shot | 2.000 s (0.50 / 0.00) |"
    assert headline[4] == "| torch-ppo | 2.000 s (0.50 / 0.00) | zero-shot | 2.000 s (0.50 / 0.00) |"
    assert full[5] == headline[5] == ("| torch-ppo-residual-random-replay | 2.000 s (0.50 / 0.00) | "
                                      "2.000 s (0.50 / 0.00) | 2.000 s (0.50 / 0.00) |")  # trained on random targets
    table = report.condition_tables([{**e, "time_ci": [1.9, 2.1], "seeds": [0], "per_seed": []}
                                     for e in entries if e["condition"] == "random-targets"])
    assert "| torch-ppo | learned, zero-shot | pd |" in table and "| torch-ppo-residual-random-replay | learned | pd |" in table


def test_the_headline_leaves_out_the_runs_that_trained_on_no_training_distribution():
    """A run trained on the C11 episode alone is zero-shot in all three training distributions: its
    rows stay in the full tables and leave the headline; a classical row and a run trained on one
    distribution's draws stay."""
    entries = [_entry("c11", kind, run, seeds=[0]) for kind, run in
               (("pd", "pd"), ("learned", "torch-ppo"), ("learned", "ppo-tuned-c11-starts"))]
    assert [e["run"] for e in report.headline_entries(entries)] == ["pd", "ppo-tuned-c11-starts"]
    assert "| torch-ppo |" in report.overview(entries) and "| torch-ppo |" not in report.headline_overview(entries)


def test_the_readme_headline_table_is_the_published_comparisons_overview():
    """README's results table is generated (agents.experiments.report.overview over the headline
    conditions) from docs/results/comparison.json, not copied by hand."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    entries = json.loads((root / "docs" / "results" / "comparison.json").read_text())["policies"]
    readme = (root / "README.md").read_text()
    start, end = "<!-- headline table: generated -->\n", "<!-- end of the headline table -->"
    assert start in readme and end in readme
    table = readme[readme.index(start) + len(start):readme.index(end)]
    overview = report.headline_overview(entries)
    assert "torch-ppo-interface-relative" not in overview  # an ablation's row: in the full tables only
    assert "| zero-shot |" in overview  # e.g. the SB3 rows trained on the C11 start, on random targets
    assert table.startswith(overview)  # and then its legend (docs/gen_pages.py's headline_legend)
    env_id = json.loads((root / "docs" / "results" / "comparison.json").read_text())["env_id"]
    assert table[len(overview):].startswith(f"\nScored on `{env_id}`: ")


def test_the_classical_rows_come_back_from_the_cache(tmp_path, monkeypatch):
    # the decision times are timed afresh on purpose (never cached): left out here
    kwargs = dict(episodes=2, verbose=False, heuristics=HEURISTICS, include_mpc=False, cache=tmp_path,
                  decision_times=False)
    first, _ = comparison.compare(None, ["c11-starts"], **kwargs)
    assert len(list(tmp_path.glob("classical-*.npz"))) == len(first) == 6  # pd, pd + shield, 4 heuristics

    def must_not_run(*args, **kwargs):
        raise AssertionError("evaluated again")

    monkeypatch.setattr(comparison, "evaluate", must_not_run)
    again, _ = comparison.compare(None, ["c11-starts"], **kwargs)
    assert again == first
    with pytest.raises(AssertionError, match="evaluated again"):  # other seeds: another key
        comparison.compare(None, ["c11-starts"], **{**kwargs, "episodes": 3})


@pytest.mark.parametrize("damage", ["truncated", "a key missing", "no trace", "NaN energy", "text success",
                                    "a reach time without success", "kept before the looser bands",
                                    "a band time without reaching it"])
def test_a_bad_cache_entry_is_evaluated_again(tmp_path, damage):
    from agents.experiments import evaluation
    from agents.files import load_arrays, save_arrays

    def result():
        return {"success": np.array([True, False]), "collisions": np.array([False, True]),
                "collision_counts": np.array([0, 2]), "reach_time": np.array([1.5, np.nan]),
                "energy": np.array([3.0, 4.0]), "peak_current_fraction": np.array([0.5, 0.9]),
                "return": np.array([-1.0, -2.0]), "seeds": np.array([7, 8]), "traces": [np.ones((4, 3))],
                "success_1e-2": np.array([True, True]), "reach_time_1e-2": np.array([1.4, 2.5]),
                "success_5e-2": np.array([True, True]), "reach_time_5e-2": np.array([1.3, 2.0])}

    runs = []

    def run():
        runs.append(1)
        return result()

    first = evaluation.cached_evaluation(tmp_path, "x", [], {"what": damage}, run)
    [entry] = tmp_path.glob("x-*.npz")
    arrays = load_arrays(entry)
    if damage == "truncated":
        entry.write_bytes(entry.read_bytes()[:100])
    else:
        if damage == "a key missing":
            del arrays["energy"]
        elif damage == "no trace":
            del arrays["traces_0"]
        elif damage == "NaN energy":
            arrays["energy"][0] = np.nan
        elif damage == "text success":
            arrays["success"] = np.array(["yes", "no"])
        elif damage == "kept before the looser bands":
            arrays = {k: v for k, v in arrays.items() if not k.endswith(("1e-2", "5e-2"))}
        elif damage == "a band time without reaching it":
            arrays["success_1e-2"][1] = False
        else:
            arrays["reach_time"][1] = 2.0
        save_arrays(entry, arrays)
    again = evaluation.cached_evaluation(tmp_path, "x", [], {"what": damage}, run)
    assert len(runs) == 2  # evaluated again, not loaded
    assert np.array_equal(again["energy"], first["energy"]) and len(again["traces"]) == 1
    evaluation.cached_evaluation(tmp_path, "x", [], {"what": damage}, run)
    assert len(runs) == 2  # and kept whole again


def test_only_and_merge_put_one_kind_of_row_into_a_published_comparison(tmp_path, monkeypatch):
    """``compare --only KIND --merge FILE``: the rows of that kind evaluated alone (the same
    episodes as the full table computes them), put into a published comparison beside their kind,
    the other entries kept as published, the command recorded; ``curves --only --merge`` alike."""
    from agents.cli import run
    from agents.experiments import curves as curves_module
    from scara_gym.benchmark.protocol import protocol_record

    monkeypatch.setattr(comparison, "tuned_heuristics", lambda verbose=False: HEURISTICS)
    kwargs = dict(episodes=1, verbose=False, heuristics=HEURISTICS, include_optimal=False, include_mpc=False)
    full = comparison.compare(None, ["wall-closer"], **kwargs)[0]  # with the robust shield's row
    published = [e for e in full if e["name"] != comparison.ROBUST_LABEL]
    path = tmp_path / "comparison.json"
    path.write_text(json.dumps({"env_id": "x", "command": "scara-agents compare (published)",
                                "conditions": protocol_record(["wall-closer"]), "targets": [],
                                "policies": published}))
    empty = tmp_path / "no-runs"
    empty.mkdir()
    entries = run(["compare", "--runs", str(empty), "--only", "robust-shield", "--merge", str(path),
                   "--out", str(tmp_path / "out")])
    names = [e["name"] for e in entries]
    assert names == [e["name"] for e in full]  # after PD's rows, where the full table has it
    fresh = entries[names.index(comparison.ROBUST_LABEL)]
    robust = full[names.index(comparison.ROBUST_LABEL)]
    assert {k: fresh[k] for k in KEYS} == {k: robust[k] for k in KEYS}  # the same episodes, the same figures
    assert [e for e in entries if e is not fresh] == published  # the others as published
    written = json.loads((tmp_path / "out" / "comparison.json").read_text())
    assert written["command"] == "scara-agents compare (published)"
    assert written["refreshed_by"]["robust-shield"].startswith("scara-agents compare --runs")
    assert written["policies"] == entries and written["targets"] == target_checks(entries)
    assert (tmp_path / "out" / "comparison.md").exists() and not list((tmp_path / "out").glob("*.png"))
    again = comparison.merge_entries(entries, [fresh], ["robust-shield"])  # replaced in place, not added
    assert [e["name"] for e in again] == names

    monkeypatch.setattr(curves_module, "CURVES", {"load mass": ("arm.load_mass", (1.0, 2.0))})
    shielded = {"pd + shield": lambda env: comparison.Shield(env, comparison.PDPolicy(env))}
    points = curves_module.curve_points(shielded, {}, 1, verbose=False)
    path = tmp_path / "curves.json"
    path.write_text(json.dumps({"episodes": 1, "curves": points, "command": "scara-agents curves (published)"}))
    data = run(["curves", "--only", "robust-shield", "--merge", str(path), "--out", str(tmp_path / "curves")])
    policies = data["curves"]["load mass"]["policies"]
    assert policies["pd + shield"] == points["load mass"]["policies"]["pd + shield"]
    assert policies[comparison.ROBUST_LABEL]["success"] == [1.0, 1.0]
    assert data["command"] == "scara-agents curves (published)" and "robust-shield" in data["refreshed_by"]
    assert (tmp_path / "curves" / "comparison_robustness.png").exists()
    monkeypatch.setattr(curves_module, "CURVES", {"load mass": ("arm.load_mass", (1.0, 3.0))})
    with pytest.raises(comparison.UserError, match="not today's"):
        curves_module.merge_curves(json.loads(path.read_text()), ["robust-shield"], verbose=False)


def _shielded_pd_as_mpc(calls: list, p95: float, record):
    """A stand-in for the MPC's episodes (the rows' logic under test, not the MPC): PD behind the
    shield with made-up solve times (95th percentile ``p95`` s); record(condition, mode) of each
    call appended to ``calls``."""
    from scara_gym.benchmark import protocol

    def stand_in(condition, episodes, cache, mode="voltage"):
        calls.append(record(condition, mode))
        result = protocol.evaluate(condition, lambda env: comparison.Shield(env, comparison.PDPolicy(env)), "pd",
                                   episodes)
        result.pop("condition")
        result["solve_time"] = {"median": 0.004, "p95": p95, "worst": 0.05, "solves": 10, "failures": 0}
        return result

    return stand_in


def test_rows_evaluated_alone_get_the_time_score_of_the_full_table(tmp_path, monkeypatch):
    """``compare --only learned``: a run's rows scored against the same references (pd + shield:
    0, the optimal replay or else the MPC: 1) as in the full table, to the last bit."""
    from agents.algorithms.torch_ppo import Config, train as train_torch_ppo

    runs = tmp_path / "runs"
    train_torch_ppo(Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16, seed=3,
                           out=str(runs / LATEST_ENV_ID / "pd" / "torch-ppo" / "seed3")))
    mpc_calls = []
    stand_in = _shielded_pd_as_mpc(mpc_calls, p95=0.005, record=lambda condition, mode: mode)
    monkeypatch.setattr(comparison, "mpc_episodes", stand_in)
    monkeypatch.setattr(comparison, "rti_episodes", stand_in)
    kwargs = dict(episodes=1, verbose=False, heuristics=HEURISTICS, decision_times=False, mpc_latency=False)
    full = {e["name"]: e for e in comparison.compare(runs, ["c11"], **kwargs)[0]}
    mpc_calls.clear()
    alone = comparison.compare(runs, ["c11"], only=("learned",), **kwargs)[0]
    assert [e["name"] for e in alone] == ["torch-ppo"] and mpc_calls == []  # the optimal replay is the reference
    scored = {k: v for k, v in full["torch-ppo"].items() if k.startswith("time_score") or k == "per_seed"}
    assert scored["time_score_reference"] == "optimal" and scored["time_score_episodes"] == 1
    assert {k: alone[0][k] for k in scored} == scored
    # without the optimal replay the MPC is the reference, evaluated beside the rows (from the cache where kept)
    alone = comparison.compare(runs, ["c11"], only=("learned",), include_optimal=False, **kwargs)[0]
    assert alone[0]["time_score_reference"] == "mpc" and mpc_calls == ["voltage"]
    without = comparison.compare(runs, ["c11"], only=("learned",), include_optimal=False, include_mpc=False,
                                 **kwargs)[0]
    assert "time_score_reference" not in without[0]  # no reference, no score: as the full table without both
    mpc_calls.clear()  # the MPC's own rows alone: its "voltage" row is also the reference, evaluated once
    rows = comparison.compare(runs, ["c11"], only=("mpc",), include_optimal=False, **kwargs)[0]
    assert mpc_calls == ["voltage", "pd", "voltage", "pd"]  # the MPC's two modes, then the real-time MPC's
    assert rows[0]["name"] == "mpc" and rows[0]["time_score_reference"] == "mpc"


def test_run_names_pick_the_runs_whose_rows_are_evaluated(tmp_path, monkeypatch):
    seen = []
    monkeypatch.setattr(comparison, "learned_runs", lambda root: {("ppo", "pd"): [tmp_path], ("sac", "pd"): [tmp_path]})
    monkeypatch.setattr(comparison._ConditionTable, "learned",
                        lambda self, groups, cache, shielded, shields=(False, True): seen.append(sorted(groups)))
    kwargs = dict(episodes=1, verbose=False, heuristics=HEURISTICS, only=("learned",), decision_times=False)
    comparison.compare(tmp_path, ["c11"], run_names=("sac",), **kwargs)
    comparison.compare(tmp_path, ["c11"], **kwargs)
    assert seen == [[("sac", "pd")], [("ppo", "pd"), ("sac", "pd")]]


def test_report_only_writes_the_targets_and_the_page_of_a_published_comparison_anew(tmp_path, capsys):
    """``compare --report-only FILE``: no episode; the entries as published, the targets and
    comparison.md written again from them (after a change to the report or the targets)."""
    from agents.cli import run

    entries = [{**e, "time_ci": [1.2, 1.4], "per_seed": []} for e in (_entry("c11", "optimal", time=1.2241, energy=43.0),
                                                        _entry("random-targets", "learned", "ppo", time=1.3, seeds=[0]))]
    path = tmp_path / "comparison.json"
    path.write_text(json.dumps({"env_id": "x", "command": "scara-agents compare (published)", "conditions": {},
                                "targets": [{"target": "an old one", "met": True, "reached": "-"}],
                                "policies": entries}))
    assert run(["compare", "--report-only", str(path), "--out", str(tmp_path / "out")]) == entries
    written = json.loads((tmp_path / "out" / "comparison.json").read_text())
    assert written["policies"] == entries and written["command"] == "scara-agents compare (published)"
    assert written["targets"] == target_checks(entries) and written["reported_by"].startswith("scara-agents compare")
    page = (tmp_path / "out" / "comparison.md").read_text()
    assert "an old one" not in page and "| ppo | learned, zero-shot |" in page
    assert "| ppo | 0 | the C11 episode's start | 2,000,000 steps | SB3 PPO, ppo.yml | untuned" in page
    for argv, says in ((["--only", "mpc"], "--report-only evaluates nothing"), ([], "is not a comparison.json")):
        if not argv:
            path.write_text(json.dumps({"policies": "none"}))
        with pytest.raises(SystemExit):  # a user's mistake: one line, exit 2
            run(["compare", "--report-only", str(path), *argv, "--out", str(tmp_path / "out")])
        assert says in capsys.readouterr().err


def test_merged_rows_go_beside_their_twin_or_their_kind_and_the_rest_is_kept():
    def row(condition, name, kind, value=0.0):
        shielded = name.endswith(" + shield")  # here the label says so; merge_entries reads the fields
        return {"condition": condition, "name": name, "kind": kind, "time_iqm": value, "control_mode": "pd",
                "shielded": shielded, "shield_range": "nominal" if shielded else None, "tags": [],
                "run": name.removesuffix(" + shield") if kind == "learned" else None}

    published = [row("a", "pd", "pd"), row("a", "mpc", "mpc"), row("a", "ppo", "learned"), row("a", "sac", "learned"),
                 row("b", "pd", "pd"), row("b", "mpc", "mpc"), row("b", "mpc (pd)", "mpc"), row("b", "ppo", "learned")]
    fresh = [row("a", "ppo + shield", "learned", 1.0), row("b", "ppo + shield", "learned", 2.0)]
    merged = comparison.merge_entries(published, fresh, ["learned-shielded"])
    assert [(e["condition"], e["name"]) for e in merged] == [
        ("a", "pd"), ("a", "mpc"), ("a", "ppo"), ("a", "ppo + shield"), ("a", "sac"),
        ("b", "pd"), ("b", "mpc"), ("b", "mpc (pd)"), ("b", "ppo"), ("b", "ppo + shield")]
    fresh = [row("b", "mpc", "mpc", 3.0)]  # b's "mpc (pd)" is not in the fresh rows: gone; a's kept
    merged = comparison.merge_entries(merged, fresh, ["mpc"])
    assert [e["time_iqm"] for e in merged if e["kind"] == "mpc"] == [0.0, 3.0]
    assert [e["name"] for e in merged if e["condition"] == "b"] == ["pd", "mpc", "ppo", "ppo + shield"]
    # learned rows of new runs: added after the condition's last learned row; the other runs' rows kept
    fresh = [row("a", "tqc", "learned", 4.0), row("b", "tqc", "learned", 5.0), row("b", "ppo", "learned", 6.0)]
    merged = comparison.merge_entries(merged, fresh, ["learned"])
    assert [(e["name"], e["time_iqm"]) for e in merged if e["condition"] == "a"] == [
        ("pd", 0.0), ("mpc", 0.0), ("ppo", 0.0), ("ppo + shield", 1.0), ("sac", 0.0), ("tqc", 4.0)]
    assert [(e["name"], e["time_iqm"]) for e in merged if e["condition"] == "b"] == [
        ("pd", 0.0), ("mpc", 3.0), ("ppo", 6.0), ("ppo + shield", 2.0), ("tqc", 5.0)]


@pytest.mark.parametrize("condition, own", [("c11-starts", 0), ("delay-1", 1)])
def test_the_mpc_under_its_own_latency_acts_its_p95_solve_time_late(monkeypatch, condition, own):
    """A row per MPC mode with ceil(p95 solve time / control step) more steps of actuation delay
    than the condition's own, named by the field added_delay; the time score's reference stays
    the MPC without it. (The MPC is stood in for by pd + shield: the rows' logic is under test.)"""

    delays = []
    stand_in = _shielded_pd_as_mpc(delays, p95=0.0251,
                                   record=lambda condition, mode: (mode, condition.env_kwargs.get("action_delay", 0)))
    monkeypatch.setattr(comparison, "mpc_episodes", stand_in)
    entries, _ = comparison.compare(None, [condition], episodes=1, verbose=False, heuristics=HEURISTICS,
                                    include_optimal=False, decision_times=False)
    assert delays == [("voltage", own), ("voltage", own + 3), ("pd", own), ("pd", own + 3)]  # 25.1 ms: 3 steps
    mpc = [e for e in entries if e["kind"] == "mpc"]
    assert [(e["name"], e["added_delay"]) for e in mpc] == [("mpc", 0), ("mpc, latency 3", 3), ("mpc (pd)", 0),
                                                            ("mpc (pd), latency 3", 3)]
    assert all(e["time_score_reference"] == "mpc" for e in entries)  # not the real-time MPC, nor a delayed one
    rti = [e for e in entries if e["kind"] == "mpc-rti"]  # the real-time MPC, and it under its own latency
    assert [e["name"] for e in rti if not e["added_delay"]] == ["mpc-rti", "mpc-rti (pd)"]
    assert all(e["name"].endswith(f"latency {e['added_delay']}") for e in rti if e["added_delay"])
    assert all(e["solve_time"]["solves"] > 0 for e in rti)
    without, _ = comparison.compare(None, [condition], episodes=1, verbose=False, heuristics=HEURISTICS,
                                    include_optimal=False, decision_times=False, mpc_latency=False)
    assert [e["name"] for e in without if e["kind"] in ("mpc", "mpc-rti")] == ["mpc", "mpc (pd)", "mpc-rti",
                                                                                "mpc-rti (pd)"]


def test_the_intervals_are_the_same_for_the_same_scores_and_leave_numpys_generator_alone():
    """rliable draws its bootstrap from numpy's global generator: seeded per call, so that a rerun
    of the comparison gives the published intervals, and given back its state."""
    scores = np.random.default_rng(0).uniform(1, 3, (5, 30))
    np.random.seed(123)
    before = np.random.get_state()[1].copy()
    first, again = statistics.iqm_with_ci(scores, reps=300), statistics.iqm_with_ci(scores, reps=300)
    assert first == again and np.array_equal(np.random.get_state()[1], before)
    assert statistics.iqm_with_ci(scores, reps=300, seed=1)[1] != first[1]  # the seed is the bootstrap's
    x, y = np.random.default_rng(1).uniform(size=(3, 20)), np.random.default_rng(2).uniform(size=(2, 20))
    assert statistics.probability_faster(x, y, reps=200) == statistics.probability_faster(x, y, reps=200)


def test_a_rate_is_claimed_with_its_exact_interval():
    """0 collisions in 150 episodes is "at most 2.4 %", never "never" (Clopper-Pearson, 95 %)."""
    assert statistics.rate_claim(0.0, 150) == "0 of 150 (at most 2.4 %)"
    low, high = statistics.rate_interval(3 / 150, 150)
    from scipy.stats import binom

    assert binom.sf(2, 150, low) == pytest.approx(0.025, abs=1e-9)  # P(X >= 3 | low) = 2.5 %
    assert binom.cdf(3, 150, high) == pytest.approx(0.025, abs=1e-9)  # P(X <= 3 | high) = 2.5 %
    assert statistics.rate_interval(1.0, 30)[1] == 1.0 and statistics.rate_interval(0.0, 30)[0] == 0.0
    assert statistics.episodes_of({"episodes": 30, "seeds": [0, 1, 2, 3, 4]}) == 150
    assert statistics.episodes_of({"episodes": 30, "seeds": None}) == 30
