"""The hyperparameter search: points decoded into blocks, the objective, and a tiny search on a local Ray runtime."""

import json

import numpy as np
import pytest

pytest.importorskip("optuna")
pytest.importorskip("ray")
from agents.experiments import search  # noqa: E402
from agents.experiments.runs import hyperparams_of  # noqa: E402
from scara_gym.benchmark import protocol  # noqa: E402


def test_a_point_becomes_a_checked_block():
    hyper = search.trial_hyperparams("ppo-c11-starts", protocol.ENV_ID, "pd",
                                     {"gamma_complement": 0.02, "net_arch": "256x256", "norm_reward": False,
                                      "use_sde": True, "log_std_init": -2.0})
    assert hyper["gamma"] == pytest.approx(0.98) and hyper["net_arch"] == [256, 256] and hyper["use_sde"] is True
    assert hyper["normalize"] == {"norm_obs": True, "norm_reward": False}
    assert hyper["env_kwargs"] == {"randomize_start": True}  # the run's own draws kept
    with pytest.raises(ValueError, match="gamma"):
        search.trial_hyperparams("ppo-c11-starts", protocol.ENV_ID, "pd", {"gamma_complement": 1.5})


def test_every_space_names_what_the_issue_asks_to_search():
    for space in search.SPACES.values():
        assert {"gamma_complement", "learning_rate", "net_arch", "norm_reward"} <= set(space)
    assert {"use_sde", "log_std_init", "ent_coef"} <= set(search.SPACES["ppo"])
    assert {"use_sde", "ent_coef"} <= set(search.SPACES["sac"])
    assert {"noise_type", "noise_std"} <= set(search.SPACES["td3"])


def test_a_gsde_run_searches_with_gsde_kept_on():
    from agents.experiments.registry import spec

    space = search.space_of(spec("ppo-gsde-c11-starts"))
    assert space["use_sde"] == ("choice", [True]) and "sde_sample_freq" in space and "log_std_init" in space
    assert search.space_of(spec("ppo-c11-starts")) == search.SPACES["ppo"]
    hyper = search.trial_hyperparams("ppo-gsde-c11-starts", protocol.ENV_ID, "pd",
                                     {"use_sde": True, "sde_sample_freq": 16, "log_std_init": -1.5})
    assert hyper["use_sde"] is True and hyper["sde_sample_freq"] == 16
    assert hyper["env_kwargs"] == {"randomize_start": True}
    with pytest.raises(ValueError, match="sde_sample_freq"):
        search.trial_hyperparams("ppo-gsde-c11-starts", protocol.ENV_ID, "pd", {"sde_sample_freq": -2})


def _result(success, collisions, times):
    result = {"collisions": np.array(collisions, dtype=bool), "reach_time": np.array(times, dtype=float)}
    for band in search.BAND_NAMES:
        result[search.band_keys(band)[0]] = np.array(success, dtype=bool)
    return result


def test_the_objective_counts_clean_successes_and_breaks_ties_by_time():
    assert search.objective(_result([1, 1, 1, 1], [0, 0, 0, 0], [1.0] * 4)) == pytest.approx(1 - 0.01)
    collided = search.objective(_result([1, 1, 1, 1], [1, 0, 0, 0], [1.0] * 4))
    assert collided == pytest.approx(0.75 - 0.01)  # a success with a collision earns nothing
    missed = search.objective(_result([0, 0, 0, 0], [0, 0, 0, 0], [np.nan] * 4))
    assert missed == pytest.approx(-0.03)  # the time limit
    assert search.rungs(100, 800) == [100, 200, 400, 800] and search.rungs(100, 500) == [100, 200, 400, 500]


def test_a_tiny_search_scores_its_trials_on_tuning_episodes_and_writes_the_best_block_twice(tmp_path):
    yaml = pytest.importorskip("yaml")
    base = hyperparams_of("ppo-c11-starts", protocol.ENV_ID)
    base.update(n_envs=2, n_steps=64, batch_size=64, n_epochs=1, eval_freq=10_000, eval_episodes=1,
                snapshot_freq=10_000, checkpoint_freq=None)
    base.pop("checkpoint_freq")
    space = dict(search.SPACES["ppo"])
    space.update(n_steps=("choice", [64]), batch_size=("choice", [64]), n_epochs=("choice", [1]))
    original = search.SPACES["ppo"]
    search.SPACES["ppo"] = space
    try:
        record = search.run_search("ppo-c11-starts", tmp_path, trials=2, max_steps=256, grace_steps=128, episodes=2,
                                   num_cpus=2, base=base)
    finally:
        search.SPACES["ppo"] = original
    assert len(record["trials"]) == 2 and record["rungs"] == [128, 256]
    assert record["trials_asked"] == record["trials_run"] == 2
    assert record["condition"].startswith("c11-starts (tuning seeds)")
    for trial in record["trials"]:
        assert trial["ended"] in ("completed", "stopped by ASHA"), trial
        assert all(r["steps"] >= 128 for r in trial["rungs"]) and -0.031 <= trial["rungs"][0]["objective"] <= 1
    best = record["trials"][record["best"]]
    assert best["steps"] == max(t["steps"] for t in record["trials"])
    written = json.loads((tmp_path / "search.json").read_text())
    assert written["best"] == record["best"]
    ours = yaml.safe_load((tmp_path / "best.yml").read_text())[protocol.ENV_ID]["pd-tuned"]
    assert ours == best["hyperparams"]
    zoo = yaml.safe_load((tmp_path / "rl_zoo.yml").read_text())[protocol.ENV_ID]
    assert zoo["policy"] == "MlpPolicy" and zoo["gamma"] == best["hyperparams"]["gamma"]
    assert zoo["policy_kwargs"].startswith("dict(net_arch=")

    # resumed on "another machine" (Ray's state gone, the record kept) with one trial more: the
    # two recorded trials are replayed from the record, not trained again, and one is new
    import shutil
    shutil.rmtree(tmp_path / "ray")
    trained = sorted(p.name for p in (tmp_path / "trials").iterdir())
    stamps = {p: p.stat().st_mtime_ns for p in (tmp_path / "trials").rglob("*") if p.is_file()}
    search.SPACES["ppo"] = space
    try:
        resumed = search.run_search("ppo-c11-starts", tmp_path, trials=3, max_steps=256, grace_steps=128, episodes=2,
                                    num_cpus=2, base=base)
        with pytest.raises(search.UserError, match="--trials"):
            search.run_search("ppo-c11-starts", tmp_path, trials=2, max_steps=256, grace_steps=128, episodes=2,
                              num_cpus=2, base=base)
    finally:
        search.SPACES["ppo"] = original
    assert resumed["trials"][:2] == record["trials"] and resumed["trials_run"] == 3
    assert resumed["trials"][2]["point"] not in [t["point"] for t in record["trials"]]
    assert all(p.stat().st_mtime_ns == stamp for p, stamp in stamps.items())
    assert len(set(p.name for p in (tmp_path / "trials").iterdir()) - set(trained)) == 1


def test_a_resumed_trial_reports_only_the_rungs_after_its_snapshot():
    """Resumed at 250 steps (its snapshot), a trial scored at 125, 250 and 500 reports 500 only:
    the earlier rungs were reported before the interruption."""
    pytest.importorskip("stable_baselines3")
    from types import SimpleNamespace

    reports = []
    callback = search.rung_callback([125, 250, 500], protocol.tuning("c11-starts", 1), 1, {}, "pd", reports.append)
    model = SimpleNamespace(num_timesteps=250, get_env=lambda: None, logger=None)
    callback.init_callback(model)
    callback.on_training_start({}, {})
    assert callback.pending == [500]
    fresh = search.rung_callback([125, 250, 500], protocol.tuning("c11-starts", 1), 1, {}, "pd", reports.append)
    fresh.init_callback(SimpleNamespace(num_timesteps=0, get_env=lambda: None, logger=None))
    fresh.on_training_start({}, {})
    assert fresh.pending == [125, 250, 500] and reports == []
    # a trial of a resumed search's record that was running when it was interrupted: its recorded
    # rungs up to the snapshot reported again, the later one (scored after the snapshot) not
    recorded = [{"steps": 125, "objective": 0.1}, {"steps": 250, "objective": 0.2}, {"steps": 500, "objective": 0.3}]
    resumed = search.rung_callback([125, 250, 500, 1000], protocol.tuning("c11-starts", 1), 1, {}, "pd",
                                   reports.append, recorded)
    resumed.init_callback(SimpleNamespace(num_timesteps=250, get_env=lambda: None, logger=None))
    resumed.on_training_start({}, {})
    assert reports == recorded[:2] and resumed.pending == [500, 1000]


def _tiny_log(tmp_path, recorded=()):
    from agents.experiments.registry import spec

    base = hyperparams_of("ppo-c11-starts", protocol.ENV_ID)
    setup = {"run": "ppo-c11-starts", "env_id": protocol.ENV_ID, "control_mode": "pd", "base": base,
             "max_steps": 256, "grace_steps": 128, "episodes": 2}
    return search.SearchLog("ppo-c11-starts", spec("ppo-c11-starts"), setup, search.SPACES["ppo"], 20, tmp_path,
                            recorded)


def _rung(steps, objective):
    return {"steps": steps, "objective": objective, "collision_rate": 0.0,
            **{f"success_{band}": 0.5 for band in search.BAND_NAMES}, "training_iteration": 3}


def test_the_search_record_on_disk_follows_every_rung_so_a_killed_search_loses_nothing_scored(tmp_path):
    yaml = pytest.importorskip("yaml")
    log = _tiny_log(tmp_path)
    on_disk = lambda: json.loads((tmp_path / "search.json").read_text())  # noqa: E731
    best_yml = lambda: yaml.safe_load((tmp_path / "best.yml").read_text())[protocol.ENV_ID]["pd-tuned"]  # noqa: E731
    log.started("a", "_trial_a", {"gamma_complement": 0.01})
    assert on_disk()["trials"][0]["ended"] == "running" and on_disk()["trials_run"] == 0
    assert not (tmp_path / "best.yml").exists()  # no trial ended: no choice yet
    log.rung("a", _rung(128, 0.2))
    assert on_disk()["trials"][0]["rungs"] == [{k: v for k, v in _rung(128, 0.2).items() if k != "training_iteration"}]
    log.started("b", "_trial_b", {"gamma_complement": 0.02})
    log.rung("b", _rung(128, 0.1))
    log.ended("b")  # ASHA stopped it at its first rung
    log.started("a", "_trial_a", {"gamma_complement": 0.01})  # Ray retries it after a failure
    assert on_disk()["trials"][0]["rungs"][0]["objective"] == 0.2  # the rung it scored is kept
    log.rung("a", _rung(256, 0.4))
    record = on_disk()
    assert [t["ended"] for t in record["trials"]] == ["running", "stopped by ASHA"]
    assert record["trials"][0]["hyperparams"]["gamma"] == pytest.approx(0.99) and record["trials_asked"] == 20
    assert record["best"] == 1  # only an ended trial is chosen
    assert best_yml()["gamma"] == pytest.approx(0.98)  # the choice so far, beside the record
    assert "1 of 20 trials run" in (tmp_path / "search.md").read_text()
    log.ended("a")
    assert on_disk()["trials"][0]["ended"] == "completed" and on_disk()["best"] == 0
    assert best_yml()["gamma"] == pytest.approx(0.99) and (tmp_path / "rl_zoo.yml").exists()


def test_a_resumed_search_keeps_the_recorded_rungs_of_the_trials_it_replays(tmp_path):
    ended = {"trial": "_trial_old", "point": {"gamma_complement": 0.01}, "rungs": [_rung(128, 0.3)], "steps": 128,
             "ended": "stopped by ASHA"}
    running = {"trial": "_trial_cut", "point": {"gamma_complement": 0.02}, "rungs": [_rung(128, 0.5)], "steps": 128,
               "ended": "running"}
    log = _tiny_log(tmp_path, [ended, running])
    log.started("x", "_trial_x", {"gamma_complement": 0.01})
    log.rung("x", _rung(128, -0.03))  # what the replay reports is not what the record keeps
    log.ended("x")
    log.started("y", "_trial_y", {"gamma_complement": 0.02})  # trains again
    record = json.loads((tmp_path / "search.json").read_text())
    assert record["trials"][0]["trial"] == "_trial_old" and record["trials"][0]["rungs"][0]["objective"] == 0.3
    assert record["trials"][1]["trial"] == "_trial_cut" and record["trials"][1]["rungs"] == []
    assert record["trials"][1]["ended"] == "running"


def test_a_search_resumes_only_a_record_of_the_same_search(tmp_path):
    with pytest.raises(search.UserError, match="max_steps"):
        search._prior_record(_write_record(tmp_path, max_steps=512), _tiny_log(tmp_path).setup,
                             search.SPACES["ppo"])
    setup = dict(_tiny_log(tmp_path).setup, episodes=5)
    with pytest.raises(search.UserError, match="--episodes"):
        search._prior_record(_write_record(tmp_path), setup, search.SPACES["ppo"])
    assert search._prior_record(tmp_path / "none.json", setup, search.SPACES["ppo"]) is None


def _write_record(tmp_path, **change):
    log = _tiny_log(tmp_path)
    log.setup = dict(log.setup, **change)
    log.write()
    return tmp_path / "search.json"


def _train_in_rl_zoo(algo, conf, tmp_path, *more):
    """RL Zoo's own command on the registered id with the block file ``conf``, seed 0, into
    tmp_path/logs, in a subprocess (importing rl_zoo3 patches gymnasium for the whole process)."""
    import os
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "rl_zoo3.train", "--algo", algo, "--env", protocol.ENV_ID,
                           "--gym-packages", "scara_gym", "--conf-file", str(conf), "-f", str(tmp_path / "logs"),
                           "--eval-freq", "-1", "--seed", "0", *more], capture_output=True, text=True, timeout=600,
                          cwd=tmp_path, env={**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")})
    assert done.returncode == 0, done.stderr[-3000:]
    return done


@pytest.mark.slow
def test_the_rl_zoo_block_trains_in_rl_zoo(tmp_path):
    """The tuned recipe in RL Zoo's format trains with RL Zoo's own command on the registered id;
    an sbx block too (RL Zoo trains SB3's implementation of the same algorithm). PPO's block is
    written the same way (the tiny search's test reads it). RL Zoo runs in its subprocess only:
    importing rl_zoo3 replaces gymnasium's TimeLimit for the whole process (rl_zoo3.gym_patches:
    an info key "TimeLimit.truncated" at the time limit), which changed the rollout digests of
    tests/test_behaviour.py run after it in the same process."""
    import importlib.util
    import sys

    import gymnasium

    if importlib.util.find_spec("rl_zoo3") is None:
        pytest.skip("rl_zoo3 is not installed (the zoo extra)")
    own_time_limit = gymnasium.wrappers.TimeLimit

    for algo, run, tiny in (("sac", "sac-c11-starts", dict(learning_starts=100, buffer_size=1000)),):
        hyper = {**hyperparams_of(run, protocol.ENV_ID), **tiny, "n_timesteps": 256}
        block = search.rl_zoo_block(algo, hyper, protocol.ENV_ID)
        assert "library" not in block and "snapshot_freq" not in block
        conf = tmp_path / f"{algo}.yml"
        search.write_yaml(conf, {protocol.ENV_ID: block})
        done = _train_in_rl_zoo(algo, conf, tmp_path)
        saved = tmp_path / "logs" / algo / f"{protocol.ENV_ID}_1"
        assert (saved / f"{protocol.ENV_ID}.zip").is_file()
        assert f"('gamma', {hyper['gamma']})" in done.stdout  # the hyperparameters RL Zoo says it trains with
    assert gymnasium.wrappers.TimeLimit is own_time_limit and "rl_zoo3" not in sys.modules


@pytest.mark.slow
def test_rl_zoo_trains_the_tuned_ppo_recipe_into_the_same_model_as_this_project(tmp_path):
    """The tuned PPO block, written in RL Zoo's format and trained by RL Zoo's own command (its
    DummyVecEnv of gym.make envs), gives bit for bit the model and normalizer that the project's
    trainer gives (its compiled vector env) for the same seed: two rollouts here, 1e7 steps in
    the experiments log. It fails if the block loses or renames a setting, or if the compiled
    vector env and the single env part ways."""
    import importlib.util
    import io
    import pickle
    import zipfile

    if importlib.util.find_spec("rl_zoo3") is None:
        pytest.skip("rl_zoo3 is not installed (the zoo extra)")
    torch = pytest.importorskip("torch")
    from agents.algorithms.sb3.training import train

    hyper = {**hyperparams_of("ppo-tuned-c11-starts", protocol.ENV_ID), "n_timesteps": 2 * 16 * 256}
    here = train("ppo", tmp_path / "here", protocol.ENV_ID, seed=0, hyperparams=hyper)
    conf = tmp_path / "ppo.yml"
    search.write_yaml(conf, {protocol.ENV_ID: search.rl_zoo_block("ppo", hyper, protocol.ENV_ID)})
    _train_in_rl_zoo("ppo", conf, tmp_path, "--num-threads", "1")
    zoo = tmp_path / "logs" / "ppo" / f"{protocol.ENV_ID}_1"

    def weights(model_zip):
        with zipfile.ZipFile(model_zip) as archive:
            return torch.load(io.BytesIO(archive.read("policy.pth")), weights_only=True)

    ours, theirs = weights(here / "model.zip"), weights(zoo / f"{protocol.ENV_ID}.zip")
    assert ours.keys() == theirs.keys() and all(torch.equal(ours[k], theirs[k]) for k in ours)
    # both pickles written by this test's own runs, in tmp_path
    normalizers = [pickle.loads(p.read_bytes()) for p in (here / "vecnormalize.pkl",
                                                          zoo / protocol.ENV_ID / "vecnormalize.pkl")]
    for stats in ("obs_rms", "ret_rms"):
        mine, zoo_stats = (getattr(n, stats) for n in normalizers)
        assert np.array_equal(mine.mean, zoo_stats.mean) and np.array_equal(mine.var, zoo_stats.var)
        assert mine.count == zoo_stats.count >= 2 * 16 * 256  # both collected the whole budget


def test_the_tuned_recipes_are_the_published_searches_best_trials():
    """A `pd-tuned` block carries the searched values of the best trial of the search the
    registry names for it (registry.TUNED_FROM: the record in results/search/RUN), only its
    budget and bookkeeping set apart; every published record's best.yml is its best trial, and a
    finished search on c11-starts' draws (the searches that give the recipes) is adopted."""
    yaml = pytest.importorskip("yaml")
    from pathlib import Path

    from agents.algorithms.sb3.hyperparams import load_hyperparams
    from agents.experiments.registry import CURVE_DRAWS, TUNED_FROM, spec

    published = Path(__file__).resolve().parents[2] / "results" / "search"
    adopted = set()
    for record_path in sorted(published.glob("*/search.json")):
        record = json.loads(record_path.read_text())
        if record.get("algorithm") not in search.SPACES or record["best"] is None:
            continue
        best = yaml.safe_load((record_path.parent / "best.yml").read_text())[record["env_id"]]
        best = best[f"{record['control_mode']}-tuned"]
        assert best == record["trials"][record["best"]]["hyperparams"]
        finished = record["trials_run"] == record["trials_asked"]
        recipes = [recipe for recipe, source in TUNED_FROM.items() if source.search == record["run"]]
        if not recipes:
            assert not (finished and spec(record["run"]).trained_on == "c11-starts"), \
                f"{record['run']}: a finished search on c11-starts that no recipe is tuned from"
            continue
        assert finished, f"{record['run']}: a recipe adopted from a search still going"
        (recipe,) = recipes
        tuned = load_hyperparams(record["algorithm"], record["env_id"], record["control_mode"],
                                 TUNED_FROM[recipe].variant)
        searched = set(search.decode(record["trials"][record["best"]]["point"])) | {"normalize"}
        assert {k: tuned[k] for k in searched} == {k: best[k] for k in searched}, record_path
        for condition in CURVE_DRAWS:  # the runs of each condition train this block
            assert hyperparams_of(f"{recipe}-tuned-{condition}", record["env_id"]).items() >= \
                {k: tuned[k] for k in searched}.items()
        adopted.add(recipe)
    assert adopted == set(TUNED_FROM)  # every recipe's search is published
