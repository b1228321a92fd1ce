"""Checkpoint selection: the fastest checkpoint that succeeds in every episode without a collision is shipped."""

import json

import pytest

pytest.importorskip("stable_baselines3")
from agents.algorithms.sb3.hyperparams import load_hyperparams  # noqa: E402
from agents.algorithms.sb3.training import train_residual_ppo  # noqa: E402
from agents.experiments import checkpoints  # noqa: E402


@pytest.fixture(scope="module")
def run_with_checkpoints(tmp_path_factory):
    hyper = load_hyperparams("ppo-residual", "Scara-C11-v0")
    hyper.update(n_envs=2, n_steps=64, batch_size=64, n_epochs=1, checkpoint_freq=128, snapshot_freq=10_000)
    out = tmp_path_factory.mktemp("run") / "ppo"
    return train_residual_ppo("pd", seed=0, total_timesteps=384, out=out, hyperparams=hyper, eval_freq=256,
                              eval_episodes=1, progress_bar=False, env_id="Scara-C11-v0")


def test_the_fastest_clean_checkpoint_is_shipped_with_its_normalizer(run_with_checkpoints, tmp_path, monkeypatch):
    run = run_with_checkpoints
    steps = sorted(int(p.stem.split("_")[1]) for p in run.glob("checkpoints/ppo_[0-9]*_steps.zip"))
    assert len(steps) >= 2
    # the evaluation is the engine's: here its rows are given, so that the rule alone is tested
    rows = [{"steps": s, "success_rate": 1.0, "collision_rate": 0.0, "mean_time": 2.0 - 0.1 * k}
            for k, s in enumerate(steps)]
    rows[-1].update(collision_rate=0.2, mean_time=1.0)  # the fastest collides: not shipped
    monkeypatch.setattr(checkpoints, "evaluate_checkpoints", lambda *args, **kwargs: rows)
    best = checkpoints.select_checkpoint(run, tmp_path / "shipped", episodes=2)
    assert best == rows[-2]
    shipped = tmp_path / "shipped"
    assert (shipped / "model.zip").read_bytes() == (run / "checkpoints" / f"ppo_{best['steps']}_steps.zip").read_bytes()
    assert (shipped / "vecnormalize.pkl").read_bytes() == \
        (run / "checkpoints" / f"ppo_vecnormalize_{best['steps']}_steps.pkl").read_bytes()
    config = json.loads((shipped / "config.json").read_text())
    assert config["selected_checkpoint"] == best and config["checkpoints"] == rows
    for row in rows:
        row["collision_rate"] = 0.5
    with pytest.raises(ValueError, match="no checkpoint"):
        checkpoints.select_checkpoint(run, tmp_path / "none", episodes=2)


def test_every_checkpoint_is_evaluated_over_the_same_seeds(run_with_checkpoints):
    rows = checkpoints.evaluate_checkpoints(run_with_checkpoints, episodes=2, seed=5000)
    assert [r["steps"] for r in rows] == sorted(r["steps"] for r in rows) and len(rows) >= 2
    for r in rows:
        assert 0.0 <= r["success_rate"] <= 1.0 and 0.0 <= r["collision_rate"] <= 1.0


def test_checkpoints_from_another_machine_are_refused_before_any_loads(run_with_checkpoints, tmp_path, monkeypatch):
    from agents import files

    assert (run_with_checkpoints / "checkpoints" / files.DIGESTS).exists()  # written with the finished run
    monkeypatch.setenv(files.TRUST_STORE_ENV, str(tmp_path / "another-machine"))
    with pytest.raises(files.UntrustedFolder, match="checkpoints: its pickle files"):
        checkpoints.evaluate_checkpoints(run_with_checkpoints, episodes=1)


def test_a_checkpoint_added_after_the_manifest_is_never_loaded(run_with_checkpoints, tmp_path):
    """A trusted checkpoints folder is trusted for the files its manifest lists, not for a pair
    of files added beside them later."""
    import os
    import pickle
    import shutil

    from agents import files

    class Payload:
        def __reduce__(self):
            return (os.system, (f"touch {tmp_path / 'ran'}",))

    run = tmp_path / "run"
    shutil.copytree(run_with_checkpoints, run)  # the same manifests: trusted as this machine's own
    shutil.copy(next(run.glob("checkpoints/ppo_[0-9]*_steps.zip")), run / "checkpoints" / "ppo_1_steps.zip")
    (run / "checkpoints" / "ppo_vecnormalize_1_steps.pkl").write_bytes(pickle.dumps(Payload()))
    with pytest.raises(ValueError, match=r"ppo_(1|vecnormalize_1)_steps\.(zip|pkl): not listed in .*SHA256SUMS"):
        checkpoints.evaluate_checkpoints(run, episodes=1)
    assert not (tmp_path / "ran").exists()
    assert files.manifest_digest(run / "checkpoints") == files.manifest_digest(run_with_checkpoints / "checkpoints")
