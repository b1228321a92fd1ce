"""agents.files: whole files or none, and loads that never run code from a file."""

import json
import os
import pickle

import numpy as np
import pytest

from agents import files


class Payload:
    """Unpickling this runs a command that leaves a mark: what a hostile file would do."""

    def __init__(self, mark):
        self.mark = str(mark)

    def __reduce__(self):
        return (os.system, (f"touch {self.mark}",))


def test_a_write_that_fails_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    target = files.write_json(tmp_path / "config.json", {"update": 1})
    def crash(*args):
        raise KeyboardInterrupt  # a kill between the write and the rename
    monkeypatch.setattr(os, "replace", crash)
    with pytest.raises(KeyboardInterrupt):
        files.write_json(target, {"update": 2})
    assert target.read_text() == '{\n  "update": 1\n}' and sorted(p.name for p in tmp_path.iterdir()) == ["config.json"]


def test_json_lines_round_trip_with_an_entry_per_line_and_nothing_padded(tmp_path):
    value = {"env_id": "Scara-C11-v2", "policies": [{"name": "pd", "ci": [1.25, 1.5]}, {"name": "mpc", "x": None}],
             "conditions": {"c11": {"seed": 1}}, "empty": [], 3: "int key"}
    path = files.write_json_lines(tmp_path / "c.json", value)
    text = path.read_text()
    assert json.loads(text) == json.loads(json.dumps(value))
    lines = text.splitlines()
    assert '{"name":"pd","ci":[1.25,1.5]},' in lines and '{"name":"mpc","x":null}' in lines
    assert '"c11":{"seed":1}' in lines and '"empty":[],' in lines
    assert not any(line.startswith(" ") for line in lines) and ": " not in text


def test_weights_round_trip_and_a_pickle_payload_is_refused_unrun(tmp_path):
    torch = pytest.importorskip("torch")
    saved = {"state_dict": {"w": torch.ones(2)}, "obs_size": 18, "clip_obs": 10.0, "steps": [1, 2]}
    files.save_torch(saved, tmp_path / "model.pt")
    loaded = files.load_torch(tmp_path / "model.pt")
    assert torch.equal(loaded["state_dict"]["w"], saved["state_dict"]["w"]) and loaded["steps"] == [1, 2]
    mark = tmp_path / "ran"
    torch.save({"state_dict": Payload(mark)}, tmp_path / "hostile.pt")
    with pytest.raises(ValueError, match=r"hostile\.pt: not a weights file"):
        files.load_torch(tmp_path / "hostile.pt")
    (tmp_path / "truncated.pt").write_bytes((tmp_path / "model.pt").read_bytes()[:40])
    with pytest.raises(ValueError, match=r"truncated\.pt"):
        files.load_torch(tmp_path / "truncated.pt")
    assert not mark.exists()


def test_a_run_folder_with_a_hostile_model_or_checkpoint_is_refused(tmp_path):
    torch = pytest.importorskip("torch")
    import gymnasium as gym

    from agents.algorithms.torch_ppo import Config, TorchPPOPolicy, train

    run = tmp_path / "run"
    config = Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16,
                    checkpoint_every=1, out=str(run))
    train(config)
    mark = tmp_path / "ran"
    for name in ("model.pt", "checkpoint.pt"):
        torch.save({"state_dict": Payload(mark), "agent": Payload(mark)}, run / name)
    (run / files.DIGESTS).unlink()  # a folder from elsewhere, without a manifest: weights_only still refuses
    with pytest.raises(ValueError, match=r"model\.pt: not a weights file"):
        TorchPPOPolicy(gym.make("Scara-C11-v1"), run)
    with pytest.raises(ValueError, match=r"checkpoint\.pt: not a weights file"):
        train(Config(**{**config.to_dict(), "total_timesteps": 32}), resume=True)
    assert not mark.exists()


def test_arrays_round_trip_and_an_object_array_is_refused_unrun(tmp_path):
    arrays = {"success": np.array([True, False]), "reach_time": np.array([1.2, np.nan])}
    files.save_arrays(tmp_path / "entry.npz", arrays)
    loaded = files.load_arrays(tmp_path / "entry.npz")
    assert np.array_equal(loaded["reach_time"], arrays["reach_time"], equal_nan=True)
    mark = tmp_path / "ran"
    np.savez(tmp_path / "hostile.npz", x=np.array([Payload(mark)], dtype=object))
    with pytest.raises(ValueError, match=r"hostile\.npz: not an array file"):
        files.load_arrays(tmp_path / "hostile.npz")
    (tmp_path / "pickled.npz").write_bytes(pickle.dumps(Payload(mark)))
    with pytest.raises(ValueError, match=r"pickled\.npz"):
        files.load_arrays(tmp_path / "pickled.npz")
    assert not mark.exists()


def test_a_run_folder_has_one_writer_and_the_second_is_told_the_holders_pid(tmp_path):
    import subprocess
    import sys
    import time

    folder = tmp_path / "run"
    with files.exclusive(folder), files.exclusive(folder):  # re-entrant within a process
        assert (folder / ".lock").read_text().strip() == str(os.getpid())
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from agents import files\n"
                               f"with files.exclusive({str(folder)!r}):\n    print('held', flush=True); time.sleep(60)"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(files.RunLocked, match=rf"pid {holder.pid}\)"):
            with files.exclusive(folder):
                pass
    finally:
        holder.kill()
        holder.wait()
    time.sleep(0.1)
    with files.exclusive(folder):  # the dead holder's lock is free at once
        pass


def test_training_into_a_folder_that_holds_a_run_needs_resume_or_overwrite(tmp_path, capsys):
    pytest.importorskip("torch")
    import json

    from agents.algorithms.torch_ppo import Config, train
    from agents.cli import run

    config = Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16,
                    out=str(tmp_path / "run"))
    train(config)
    with pytest.raises(ValueError, match="holds this run already; resume=True .* overwrite=True"):
        train(config)
    assert train(config, resume=True)["global_step"] == 16  # finished: nothing more to train
    longer = Config(**{**config.to_dict(), "total_timesteps": 32})  # a budget may grow on resume
    assert train(longer, resume=True)["global_step"] == 32
    other = Config(**{**config.to_dict(), "hidden_size": 32})
    with pytest.raises(ValueError, match=r"holds another run \(hidden_size 64 \(this run: 32\)\)"):
        train(other, resume=True)
    assert train(other, overwrite=True)["global_step"] == 16  # replaced: trained from scratch
    assert json.loads((tmp_path / "run" / "config.json").read_text())["hidden_size"] == 32
    record = json.loads((tmp_path / "run" / files.RUN_RECORD).read_text())
    files.write_json(tmp_path / "run" / files.RUN_RECORD, {**record, "run_format": files.RUN_FORMAT + 1})
    with pytest.raises(ValueError, match="written by a newer version of scara_gym"):
        train(other, resume=True)
    with pytest.raises(SystemExit) as exit_:
        run(["torch-ppo", "--out", str(tmp_path / "fresh"), "--resume"])
    assert exit_.value.code == 2 and "holds no checkpoint.pt" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        run(["torch-ppo", "--out", str(tmp_path / "fresh"), "--resume", "--overwrite"])
    assert exit_.value.code == 2 and "exclude each other" in capsys.readouterr().err


def test_a_run_of_one_trainer_is_not_resumed_by_another(tmp_path):
    pytest.importorskip("stable_baselines3")
    import shutil
    from pathlib import Path

    from agents.algorithms.torch_ppo import Config, train

    shipped = Path(__file__).resolve().parents[2] / "agents" / "models" / "ppo_pd"
    folder = tmp_path / "sb3-run"
    shutil.copytree(shipped, folder)
    config = Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16, out=str(folder))
    with pytest.raises(ValueError, match=r"holds another run \(trainer 'sb3' \(this run: 'torch-ppo'\)"):
        train(config, resume=True)
    assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for p in shipped.iterdir())  # nothing added


def _untrusted_copy(tmp_path, extra_line: bool = True):
    """A copy of a shipped SB3 model whose manifest lists one more file: the same policy, a
    manifest neither the package nor this machine vouches for."""
    import shutil
    from pathlib import Path

    shipped = Path(__file__).resolve().parents[2] / "agents" / "models" / "ppo_pd"
    copy = tmp_path / "from-elsewhere"
    shutil.copytree(shipped, copy)
    (copy / "NOTES").write_text("sent by someone\n")
    manifest = (copy / files.DIGESTS).read_text() + f"{files.file_digest(copy / 'NOTES')}  NOTES\n"
    (copy / files.DIGESTS).write_text(manifest)
    return copy


def test_sb3_folders_load_only_when_shipped_published_own_or_trusted(tmp_path, capsys, monkeypatch):
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    from agents.algorithms.sb3.policy import PPOPolicy, SB3Policy
    from agents.cli import run

    env = gym.make("Scara-C11-v0")
    PPOPolicy(env, "ppo_pd")  # shipped: its manifest is in the package's list
    copy = _untrusted_copy(tmp_path)
    with pytest.raises(files.UntrustedFolder, match=r"from-elsewhere: its pickle files .* pass --trust"):
        SB3Policy(env, copy)
    SB3Policy(env, copy, trust=True)  # the user vouches for it
    with pytest.raises(SystemExit) as exit_:
        run(["evaluate", "--env-id", "Scara-C11-v0", "--policies", f"sb3:{copy}", "--episodes", "1",
             "--out", str(tmp_path / "results")])
    error = capsys.readouterr().err
    assert exit_.value.code == 2 and len(error.strip().splitlines()) == 1 and "--trust" in error
    assert not (tmp_path / "results").exists()
    rows = run(["evaluate", "--env-id", "Scara-C11-v0", "--policies", f"sb3:{copy}", "--episodes", "1", "--trust",
                "--out", str(tmp_path / "results")])
    assert rows[0]["episodes"] == 1 and files.TRUST_ENV not in os.environ  # --trust lasts one command
    torch_run = tmp_path / "torch-run"
    files.write_json(torch_run / "config.json", {"algo": "torch-ppo"})
    (torch_run / "model.pt").write_bytes(b"weights")
    with pytest.raises(FileNotFoundError, match=r"torch-run: no SB3 model\.zip \(a torch PPO run: torchppo:DIR\)"):
        SB3Policy(env, torch_run)
    files.record_trusted(copy)  # as a run on this machine records its own
    SB3Policy(env, copy)
    monkeypatch.setenv(files.TRUST_STORE_ENV, str(tmp_path / "another-machine"))
    with pytest.raises(files.UntrustedFolder):
        SB3Policy(env, copy)


def test_a_hostile_pickle_in_an_sb3_folder_never_runs(tmp_path):
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    from agents.algorithms.sb3.policy import SB3Policy

    copy = _untrusted_copy(tmp_path)
    mark = tmp_path / "ran"
    (copy / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(mark)))
    files.write_digests(copy, files.POLICY_FILES)  # a consistent manifest: the digests cannot tell
    with pytest.raises(files.UntrustedFolder):
        SB3Policy(gym.make("Scara-C11-v0"), copy)
    assert not mark.exists()


def test_the_trust_store_records_a_manifest_once_in_whole_lines(tmp_path, monkeypatch):
    monkeypatch.setenv(files.TRUST_STORE_ENV, str(tmp_path / "store"))
    folder = tmp_path / "run"
    files.write_json(folder / "config.json", {"algo": "ppo"})
    files.write_digests(folder, files.POLICY_FILES)
    assert not files.is_trusted(folder)
    (tmp_path / "store").write_text("0123abcd")  # a line a crash cut short
    files.record_trusted(folder)
    files.record_trusted(folder)
    assert (tmp_path / "store").read_text().splitlines() == ["0123abcd", files.manifest_digest(folder)]
    assert files.is_trusted(folder)
    files.write_json(folder / "config.json", {"algo": "sac"})
    with pytest.raises(ValueError, match=r"config\.json: its SHA-256"):  # a trusted manifest, a changed file
        files.require_trusted(folder)


@pytest.mark.slow
def test_a_run_killed_at_random_instants_resumes_to_the_same_end(tmp_path):
    """SIGKILL at random instants (checkpoints are written every update, so some kills land in
    a write): every restart resumes from the last complete checkpoint, and the run ends with
    the updates and steps of an unkilled one."""
    import json
    import signal
    import subprocess
    import sys
    import time

    torch = pytest.importorskip("torch")
    out = tmp_path / "run"
    flags = ["--num-envs", "2", "--num-steps", "8", "--num-minibatches", "1", "--update-epochs", "1",
             "--total-timesteps", "1600", "--checkpoint-every", "1", "--out", str(out)]
    rng = np.random.default_rng(0)
    kills, updates_seen = 0, []

    def start():
        resume = ["--resume"] if (out / "checkpoint.pt").exists() else []
        return subprocess.Popen([sys.executable, "-m", "agents", "torch-ppo", *flags, *resume],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)

    def saved_update():
        try:
            return files.load_torch(out / "checkpoint.pt")["update"]
        except (ValueError, FileNotFoundError):
            return 0

    for _ in range(4):  # each start is killed at a random instant after it made progress
        before = saved_update()
        process = start()
        deadline = time.monotonic() + 300
        while process.poll() is None and saved_update() <= before and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(float(rng.uniform(0.0, 0.5)))
        if process.poll() is not None:
            assert process.returncode == 0, process.stderr.read()
            break
        process.send_signal(signal.SIGKILL)
        process.wait()
        kills += 1
        updates_seen.append(saved_update())
    process = start()  # the last restart runs to the end
    assert process.wait(timeout=600) == 0, process.stderr.read()
    assert kills >= 2 and len(updates_seen) >= 2, (kills, updates_seen)
    assert updates_seen == sorted(updates_seen) and updates_seen[-1] < 100
    summary = json.loads((out / "summary.json").read_text())
    assert summary["global_step"] == 1600 and files.load_torch(out / "checkpoint.pt")["update"] == 100
    assert not list(out.glob(".*.partial"))
    assert torch.isfinite(files.load_torch(out / "model.pt")["state_dict"]["actor_logstd"]).all()


def test_every_shipped_and_published_model_folder_matches_its_manifest_and_is_published():
    """The shipped models' manifests are the package's list (agents/shipped_manifests.txt), the
    published runs' the list beside them (results/runs/published_manifests.txt): each folder in
    its own list, and nothing else in either."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    lists = {"agents/models/*": files.SHIPPED_MANIFESTS,
             "results/runs/*/*/*/seed*": root / "results" / "runs" / files.PUBLISHED_LIST}
    assert files.CHECKOUT_RUNS == root / "results" / "runs"
    total = 0
    for pattern, listing in lists.items():
        folders = list(root.glob(pattern))
        total += len(folders)
        listed = set(listing.read_text().split())  # the committed list, not the tests' copy
        for folder in folders:
            assert (folder / files.DIGESTS).exists(), folder
            files.verify_digests(folder)
            assert files.manifest_digest(folder) in listed, folder  # trusted on every machine
        assert len(listed) == len({files.manifest_digest(f) for f in folders})  # and nothing else
    assert total > 50


def test_published_runs_are_trusted_where_the_user_says_and_published_beside_them(tmp_path, monkeypatch):
    """A run published into a folder of runs is listed in that folder's published_manifests.txt
    (never a file of the package), and trusted where that folder is the published runs
    ($SCARA_GYM_PUBLISHED_RUNS, or the clone's results/runs); without any, a command that needs
    them says in one line how to get them."""
    monkeypatch.delenv(files.PUBLISHED_MANIFESTS_ENV)
    monkeypatch.delenv(files.PUBLISHED_RUNS_ENV, raising=False)
    monkeypatch.setattr(files, "CHECKOUT_RUNS", tmp_path / "no-clone" / "results" / "runs")
    runs = tmp_path / "published"
    run = runs / "Scara-C11-v1" / "pd" / "some-run" / "seed0"
    run.mkdir(parents=True)
    (run / "config.json").write_text("{}")
    files.write_digests(run, ["config.json"])
    assert files.published_runs() is None and not files.is_trusted(run)
    with pytest.raises(files.UserError, match="SCARA_GYM_PUBLISHED_RUNS=CLONE/results/runs"):
        files.require_published_runs()
    with pytest.raises(files.UserError, match="no folder '/nowhere' of published runs"):
        files.require_published_runs("/nowhere")
    files.publish_manifest(run, runs / files.PUBLISHED_LIST)
    assert (runs / files.PUBLISHED_LIST).read_text() == files.manifest_digest(run) + "\n"
    assert not files.is_trusted(run)  # a list is read only where the user says the published runs are
    monkeypatch.setenv(files.PUBLISHED_RUNS_ENV, str(runs))
    assert files.published_runs() == runs and files.is_trusted(run) and files.require_published_runs() == runs
    monkeypatch.delenv(files.PUBLISHED_RUNS_ENV)
    monkeypatch.setattr(files, "CHECKOUT_RUNS", runs)  # a clone's results/runs
    assert files.published_runs() == runs and files.is_trusted(run)


def test_a_corrupted_model_file_is_refused_by_its_digest(tmp_path):
    import shutil
    from pathlib import Path

    import gymnasium as gym

    pytest.importorskip("stable_baselines3")
    from agents.algorithms.sb3.policy import PPOPolicy

    shipped = Path(__file__).resolve().parents[2] / "agents" / "models" / "ppo_pd"
    copy = tmp_path / "ppo_pd"
    shutil.copytree(shipped, copy)
    PPOPolicy(gym.make("Scara-C11-v0"), copy)  # intact: loads
    data = bytearray((copy / "model.zip").read_bytes())
    data[len(data) // 2] ^= 0x01  # one flipped bit
    (copy / "model.zip").write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"model\.zip: its SHA-256 is not the one .*SHA256SUMS records"):
        PPOPolicy(gym.make("Scara-C11-v0"), copy)
    (copy / "vecnormalize.pkl").unlink()
    (copy / "model.zip").write_bytes((shipped / "model.zip").read_bytes())
    with pytest.raises(ValueError, match=r"vecnormalize\.pkl: listed in .* but missing"):
        PPOPolicy(gym.make("Scara-C11-v0"), copy)


def test_a_finished_torch_run_carries_its_manifest_and_a_changed_weight_is_refused(tmp_path):
    torch = pytest.importorskip("torch")
    import gymnasium as gym

    from agents.algorithms.torch_ppo import Config, TorchPPOPolicy, train

    run = tmp_path / "run"
    train(Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16, out=str(run)))
    files.verify_digests(run)
    assert {line.split()[1] for line in (run / files.DIGESTS).read_text().splitlines()} == {"config.json", "model.pt"}
    saved = files.load_torch(run / "model.pt")
    saved["state_dict"]["actor_logstd"] += 1.0
    torch.save(saved, run / "model.pt")
    with pytest.raises(ValueError, match=r"model\.pt: its SHA-256"):
        TorchPPOPolicy(gym.make("Scara-C11-v1"), run)
    with pytest.raises(ValueError, match=r"model\.pt: its SHA-256"):
        train(Config(num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, total_timesteps=16,
                     init_from=str(run), out=str(tmp_path / "fine-tune")))


# -- trust as content (issue 52) ----------------------------------------------------------------
def _shipped(name="ppo_pd"):
    from pathlib import Path

    return Path(__file__).resolve().parents[2] / "agents" / "models" / name


def _hostile_model_zip(path, mark) -> None:
    """A model.zip whose ``data`` holds a serialized object, as SB3 writes its policy class: loading
    it unpickles ``Payload(mark)``."""
    import base64
    import json
    import zipfile

    with zipfile.ZipFile(_shipped() / "model.zip") as genuine, zipfile.ZipFile(path, "w") as hostile:
        for name in genuine.namelist():
            data = genuine.read(name)
            if name == "data":
                record = json.loads(data)
                record["policy_class"] = {":type:": "<class 'type'>",
                                          ":serialized:": base64.b64encode(pickle.dumps(Payload(mark))).decode()}
                data = json.dumps(record).encode()
            hostile.writestr(name, data)


def test_an_empty_manifest_trusts_nothing_and_is_never_recorded(tmp_path, capsys):
    import hashlib
    import shutil

    from agents.cli import run

    nothing = hashlib.sha256(b"").hexdigest()
    empty = tmp_path / "checkpoints"
    empty.mkdir()
    (empty / files.DIGESTS).write_text("")  # what an SB3 run with checkpoint_freq and no checkpoint wrote
    try:
        files.record_trusted(empty)
    except ValueError as error:
        assert "lists no file" in str(error)
    store = files.trust_store()
    assert not store.exists() or nothing not in store.read_text().split()
    hostile = tmp_path / "hostile"
    hostile.mkdir()
    shutil.copy(_shipped() / "config.json", hostile / "config.json")
    (hostile / files.DIGESTS).write_text("")
    mark = tmp_path / "ran"
    _hostile_model_zip(hostile / "model.zip", mark)
    with pytest.raises(SystemExit) as exit_:
        run(["evaluate", "--env-id", "Scara-C11-v0", "--policies", f"sb3:{hostile}", "--episodes", "1",
             "--out", str(tmp_path / "results")])
    error = capsys.readouterr().err
    assert not mark.exists()
    assert exit_.value.code == 2 and len(error.strip().splitlines()) == 1 and "lists no file" in error


def test_a_file_present_but_not_listed_is_never_loaded(tmp_path):
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    from agents.algorithms.sb3.policy import SB3Policy

    folder = tmp_path / "run"
    shutil_copy = __import__("shutil").copytree
    shutil_copy(_shipped(), folder)
    mark = tmp_path / "ran"
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(mark)))
    files.write_digests(folder, ["config.json", "model.zip"])  # a run without a normalizer, say
    files.record_trusted(folder)  # trusted, but for these two files only
    with pytest.raises(ValueError, match=r"run/vecnormalize\.pkl: not listed in .*SHA256SUMS"):
        SB3Policy(gym.make("Scara-C11-v0"), folder)
    assert not mark.exists()


def test_a_file_swapped_after_its_check_is_not_the_one_loaded(tmp_path, monkeypatch):
    """The race of a check, then a reopen: the attacker swaps the file the moment its digest is
    taken. What loads must be the bytes that were hashed."""
    pytest.importorskip("stable_baselines3")
    import hashlib
    import shutil

    import gymnasium as gym

    from agents.algorithms.sb3.policy import PPOPolicy

    folder = tmp_path / "ppo_pd"
    shutil.copytree(_shipped(), folder)  # the shipped manifest: trusted everywhere
    genuine = (folder / "vecnormalize.pkl").read_bytes()
    mark = tmp_path / "ran"
    sha256 = hashlib.sha256

    def racing(data=b"", *args, **kwargs):
        digest = sha256(data, *args, **kwargs)
        if bytes(data) == genuine:  # just checked: the attacker wins the race
            (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(Payload(mark)))
        return digest

    monkeypatch.setattr(hashlib, "sha256", racing)
    policy = PPOPolicy(gym.make("Scara-C11-v0"), folder)
    monkeypatch.setattr(hashlib, "sha256", sha256)
    assert not mark.exists()
    assert policy.normalizer is not None  # the genuine normalizer, from the bytes that were checked


@pytest.mark.parametrize("mistake", ["symlink", "group-writable", "world-writable"])
def test_a_trust_store_others_could_write_is_refused(tmp_path, monkeypatch, mistake):
    folder = tmp_path / "run"
    files.write_json(folder / "config.json", {"algo": "ppo"})
    files.write_digests(folder, files.POLICY_FILES)
    store = tmp_path / "store"
    if mistake == "symlink":
        elsewhere = tmp_path / "someone-elses"
        elsewhere.write_text(f"{files.manifest_digest(folder)}\n")
        elsewhere.chmod(0o600)
        store.symlink_to(elsewhere)
    else:
        store.write_text(f"{files.manifest_digest(folder)}\n")
        store.chmod(0o620 if mistake == "group-writable" else 0o602)
    monkeypatch.setenv(files.TRUST_STORE_ENV, str(store))
    for act in (files.is_trusted, files.require_trusted, files.record_trusted):
        with pytest.raises(ValueError, match=rf"{store}: the trust store .*(a symlink|writable by)"):
            act(folder)


def test_a_run_refused_after_its_folder_was_claimed_leaves_nothing_behind(tmp_path):
    new, old = tmp_path / "new", tmp_path / "old"
    old.mkdir()
    (old / "NOTES").write_text("mine\n")
    for folder in (new, old):
        with pytest.raises(ValueError, match="refused after the claim"):
            with files.exclusive(folder):
                files.claim_run_folder(folder, {"trainer": "bc", "seed": 0}, resume=False, overwrite=False)
                raise ValueError("refused after the claim")  # as a dataset or a device refused there would be
    assert not new.exists() and sorted(p.name for p in old.iterdir()) == ["NOTES"]
    with pytest.raises(KeyboardInterrupt):
        with files.exclusive(new):
            files.claim_run_folder(new, {"trainer": "bc", "seed": 0}, resume=False, overwrite=False)
            files.write_json(new / "summary.json", {})  # it got further: what it wrote stays, for a resume
            raise KeyboardInterrupt
    assert sorted(p.name for p in new.iterdir()) == [".lock", files.RUN_RECORD, "summary.json"]
