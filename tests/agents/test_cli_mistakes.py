"""A catalogue of mistakes on every subcommand of scara-agents: each ends at once with exit status
2 and one line on stderr that names the argument, no traceback, and nothing left behind."""

import re
import time

import pytest

from agents.cli import run

MISTAKES = [
    # evaluate
    (["evaluate", "--policies", "nonsense"], "unknown policy 'nonsense'"),
    (["evaluate", "--policies", "ppo:"], "ppo policies are given as ppo:"),
    (["evaluate", "--policies", "sb3:"], "sb3 policies are given as sb3:RUN_DIR"),
    (["evaluate", "--policies", "torchppo:"], "torchppo policies are given as"),
    (["evaluate", "--policies", "shield:"], "shield:SPEC"),
    (["evaluate", "--policies", "sb3:/nonexistent"], "/nonexistent"),
    (["evaluate", "--policies", "torchppo:/nonexistent"], "/nonexistent"),
    (["evaluate", "--policies", "ppo:no_such_model"], "no_such_model"),
    (["evaluate", "--policies", "dec-continue:abc"], "dec-continue"),
    (["evaluate", "--policies", "dec-restart:-1"], "critical_distance"),
    (["evaluate", "--policies", "mpc:horizon=3"], "the MPC is given as mpc"),
    (["evaluate", "--policies", "mpc-rti:horizon=3"], "the real-time MPC is given as mpc-rti"),
    (["evaluate", "--policies", "optimal"], "control_mode='voltage'"),
    (["evaluate", "--condition", "c12"], "--condition: invalid choice: 'c12'"),
    (["evaluate", "--episodes", "0"], "--episodes must be >= 1"),
    (["evaluate", "--episodes", "-3"], "--episodes must be >= 1"),
    (["evaluate", "--episodes", "many"], "--episodes: invalid int value"),
    (["evaluate", "--seed", "-1"], r"--seed must be an integer in \[0, 4294967295\]"),
    (["evaluate", "--seed", "99999999999999999999999"], r"--seed must be an integer in \[0, 4294967295\]"),
    (["evaluate", "--out", ""], "argument --out: an empty path; give a folder"),
    (["evaluate", "--seed", "1.5"], "--seed: invalid int value"),
    (["evaluate", "--env-id", "Scara-C11-v9"], "--env-id: invalid choice"),
    (["evaluate", "--control-mode", "current"], "--control-mode: invalid choice"),
    (["evaluate", "--no-such-flag"], "unrecognized arguments: --no-such-flag"),
    (["evaluate", "--policies", "bc:"], "bc policies are given as bc:RUN_DIR"),
    (["evaluate", "--policies", "bc:/nonexistent"], "/nonexistent"),
    # datasets
    (["datasets", "build"], "needs a dataset id or 'all'"),
    (["datasets", "build", "scara/c12/expert-v0"], "unknown dataset 'scara/c12/expert-v0'"),
    (["datasets", "build", "scara/c11/random-v0", "--episodes", "0"], "--episodes must be >= 1"),
    (["datasets", "make"], "invalid choice: 'make'"),
    (["datasets", "build", "scara/c11/expert-v0", "--runs", "/nonexistent"],
     "no folder '/nonexistent' of published runs; .* --runs CLONE/results/runs"),
    # train
    (["train", "bc-c11-expert", "--set", "hidden_sise=3"], "not BCConfig fields"),
    (["train", "bc-c11-expert", "--set", "steps=0"], "steps must be an integer >= 1"),
    (["train", "bc-c11-expert", "--control-mode", "voltage"], "clones a 'pd' mode dataset"),
    (["train", "no-such-run"], "invalid choice: 'no-such-run'"),
    (["train", "torch-ppo", "--set", "hidden_sise=3"], "not torch PPO Config fields"),
    (["train", "torch-ppo", "--set", "noequals"], "--set takes NAME=VALUE"),
    (["train", "torch-ppo", "--set", "=3"], "--set takes NAME=VALUE"),
    (["train", "torch-ppo", "--set", "hidden_size=0"], "hidden_size must be an integer >= 1"),
    (["train", "torch-ppo", "--set", "hidden_size=big"], "--hidden-size takes a number"),
    (["train", "torch-ppo", "--set", "learning_rate=nan"], "learning_rate must be"),
    (["train", "torch-ppo", "--set", "learning_rate=-0.1"], "learning_rate must be"),
    (["train", "torch-ppo", "--set", "gamma=2"], "gamma must be"),
    (["train", "torch-ppo", "--set", "gae_lambda=0"], "gae_lambda must be"),
    (["train", "torch-ppo", "--set", "num_minibatches=7"], "num_minibatches must divide"),
    (["train", "torch-ppo", "--set", "update_epochs=0"], "update_epochs must be an integer >= 1"),
    (["train", "torch-ppo", "--set", "num_steps=0"], "num_steps must be an integer >= 1"),
    (["train", "torch-ppo", "--set", "device=tpu"], "device must be one of"),
    (["train", "torch-ppo", "--set", "randomize_params=everything"], "randomize_params must be one of"),
    (["train", "torch-ppo", "--set", "sensor_noise=-1"], "sensor_noise must be"),
    (["train", "torch-ppo", "--set", "clip_coef=0"], "clip_coef must be"),
    (["train", "torch-ppo", "--set", "residual_scale=1,2"], "residual_scale: expected 3 numbers"),
    (["train", "torch-ppo", "--set", "reward_weights=energy"], "reward_weights: expected name=number"),
    (["train", "torch-ppo", "--set", "anneal_lr=maybe"], "--anneal-lr takes true or false"),
    (["train", "torch-ppo", "--total-timesteps", "0"], "--total-timesteps must be >= 1"),
    (["train", "torch-ppo", "--total-timesteps", "-1"], "--total-timesteps must be >= 1"),
    (["train", "torch-ppo", "--seed", "-1"], r"--seed must be an integer in \[0, 4294967295\]"),
    (["train", "torch-ppo", "--set", "env_id=Scara-C11-v0"], "--set env_id: give it as --env-id"),
    (["train", "bc-c11-expert", "--set", "seed=3"], "--set seed: give it as --seed"),
    (["train", "torch-ppo", "--env-id", "nope"], "--env-id: invalid choice"),
    (["train", "sac", "--randomize-target"], "--randomize-target is for the ppo-residual runs"),
    (["train", "sac", "--set", "learning_rate=nan"], "learning_rate must be"),
    (["train", "sac", "--set", "gamma=2"], "gamma must be"),
    (["train", "sac", "--set", "batch_size=0"], "batch_size must be an integer >= 1"),
    (["train", "sac", "--set", "bogus=1"], "the YAML block lacks"),
    (["train", "sac", "--set", "tau=0"], "tau must be"),
    (["train", "sac", "--set", "ent_coef=-1"], "ent_coef must be"),
    (["train", "ppo", "--set", "n_steps=0"], "n_steps must be an integer >= 1"),
    (["train", "ppo", "--set", "net_arch=[0]"], "net_arch must be a list of layer widths"),
    (["train", "ppo", "--set", "n_epochs=0"], "n_epochs must be an integer >= 1"),
    (["train", "ppo", "--set", "clip_range=0"], "clip_range must be"),
    (["train", "td3", "--set", "noise_std=-1"], "noise_std must be"),
    (["train", "td3", "--set", "learning_starts=-5"], "learning_starts must be an integer >= 0"),
    (["train", "ppo-residual", "--set", "n_envs=0"], r"n_envs must be an integer in \[1, "),
    (["train", "sac", "--total-timesteps", "0"], "--total-timesteps must be >= 1"),
    # torch-ppo
    (["torch-ppo", "--num-steps", "0"], "num_steps must be an integer >= 1"),
    (["torch-ppo", "--update-epochs", "0"], "update_epochs must be an integer >= 1"),
    (["torch-ppo", "--learning-rate", "nan"], "learning_rate must be"),
    (["torch-ppo", "--learning-rate", "-1"], "learning_rate must be"),
    (["torch-ppo", "--learning-rate", "fast"], "--learning-rate takes a number"),
    (["torch-ppo", "--gamma", "2"], "gamma must be"),
    (["torch-ppo", "--gae-lambda", "0"], "gae_lambda must be"),
    (["torch-ppo", "--hidden-size", "0"], "hidden_size must be an integer >= 1"),
    (["torch-ppo", "--num-envs", "0"], r"num_envs must be an integer in \[1, "),
    (["torch-ppo", "--num-minibatches", "3"], "num_minibatches must divide"),
    (["torch-ppo", "--num-minibatches", "0"], "num_minibatches must be an integer >= 1"),
    (["torch-ppo", "--total-timesteps", "-1"], "total_timesteps must be an integer >= 1"),
    (["torch-ppo", "--device", "tpu"], "device must be one of"),
    (["torch-ppo", "--env-id", "nope"], "env_id must be one of"),
    (["torch-ppo", "--control-mode", "current"], "control_mode must be one of"),
    (["torch-ppo", "--randomize-params", "nope"], "randomize_params must be one of"),
    (["torch-ppo", "--residual-scale", "1,2"], "residual_scale: expected 3 numbers"),
    (["torch-ppo", "--residual-scale", "a,b,c"], "residual_scale: expected 3 numbers"),
    (["torch-ppo", "--residual-scale", "1,-2,3"], "residual_scale must be"),
    (["torch-ppo", "--reward-weights", "time"], "reward_weights: expected name=number"),
    (["torch-ppo", "--seed", "-1"], r"seed must be an integer in \[0, 4294967295\]"),
    (["torch-ppo", "--seed", str(2**64)], r"seed must be an integer in \[0, 4294967295\]"),
    (["torch-ppo", "--device", "cuda", "--out", "gpu-run"], "device='cuda'"),
    (["torch-ppo", "--clip-obs", "0"], "clip_obs must be"),
    (["torch-ppo", "--max-grad-norm", "0"], "max_grad_norm must be"),
    (["torch-ppo", "--ent-coef", "-0.1"], "ent_coef must be"),
    (["torch-ppo", "--vf-coef", "inf"], "vf_coef must be"),
    (["torch-ppo", "--demo-resets", "2"], "demo_resets must be"),
    (["torch-ppo", "--target-replay", "-0.5"], "target_replay must be"),
    (["torch-ppo", "--sensor-noise", "nan"], "sensor_noise must be"),
    (["torch-ppo", "--env-threads", "0"], "env_threads must be an integer >= 1"),
    (["torch-ppo", "--checkpoint-every", "0"], "checkpoint_every must be an integer >= 1"),
    (["torch-ppo", "--demo-bc-decay", "0"], "demo_bc_decay must be"),
    (["torch-ppo", "--init-log-std", "nan"], "init_log_std must be"),
    (["torch-ppo", "--resume", "--out", "nothing_here"], "--resume: nothing_here holds no checkpoint.pt"),
    (["torch-ppo", "--resume", "--overwrite"], "--resume and --overwrite exclude each other"),
    (["train", "sac", "--resume", "--overwrite"], "--resume and --overwrite exclude each other"),
    # campaign
    (["campaign", "no-such-run"], "no registered run 'no-such-run'"),
    (["campaign", "--seeds", "-1"], r"--seeds must be integers in \[0, 4294967295\]"),
    (["campaign", "--publish", "x", "--runs", "/nonexistent"], "--runs: no folder '/nonexistent' to publish from"),
    (["campaign", "--seeds", "a"], "--seeds: invalid int value"),
    (["campaign", "--total-timesteps", "0"], "--total-timesteps must be >= 1"),
    (["campaign", "--shard", "2/2"], "--shard must be K/N"),
    (["campaign", "--shard", "x"], "--shard must be K/N"),
    (["campaign", "--env-id", "nope"], "--env-id: invalid choice"),
    # compare
    (["compare", "--runs", "/nonexistent"], "--runs: no folder"),
    (["compare", "--shield", "nosuch"], r"--shield names \['nosuch'\], which are not registered runs"),
    (["compare", "--run-names", "nosuch"], r"--run-names names \['nosuch'\], which are not registered runs"),
    (["compare", "--episodes", "0"], "--episodes must be >= 1"),
    (["compare", "--jobs", "0"], "--jobs must be >= 1"),
    (["compare", "--conditions", "c12"], "--conditions: invalid choice"),
    (["compare", "--runs", ".", "--merge", "published.json"], "--merge needs --only KIND"),
    (["compare", "--only", "everything"], "--only: invalid choice"),
    (["compare", "--runs", ".", "--only", "mpc", "--merge", "/nonexistent.json"], "--merge: no file"),
    # curves
    (["curves", "--episodes", "0"], "--episodes must be >= 1"),
    (["curves", "--only", "robust-shield"], "--only needs --merge FILE"),
    (["curves", "--only", "pd"], "--only: invalid choice"),
    (["curves", "--episodes", "x"], "--episodes: invalid int value"),
    # sweep
    (["sweep", "--run", "ppo", "--grid", "learning_rat=0.1"], "does not have|do not have"),
    (["sweep", "--run", "nosuch"], "--run: invalid choice"),
    (["sweep", "--run", "ppo", "--episodes", "0"], "--episodes must be >= 1"),
    (["sweep", "--run", "ppo", "--cpus-per-trial", "-1"], "--cpus-per-trial must be"),
    (["sweep", "--run", "ppo", "--seeds", "-1"], "--seeds must be"),
    (["train", "ppo", "--seed", str(2**40)], r"--seed must be an integer in \[0, 4294967295\]"),
    (["sweep", "--run", "ppo", "--total-timesteps", "0"], "--total-timesteps must be"),
    (["sweep", "--run", "ppo", "--max-concurrent", "0"], "--max-concurrent must be"),
    (["sweep", "--run", "torch-ppo", "--grid", "learning_rate=nan"], "learning_rate must be"),
    (["sweep", "--run", "ppo", "--grid", "n_steps=0"], "n_steps must be an integer >= 1"),
    (["sweep", "--run", "ppo", "--grid", "learning_rate=../.."], "not a plain name and value"),
    # learning-curve
    (["learning-curve", "ppo"], "ppo is not a learning-curve run; those are ppo-c11-starts"),
    (["learning-curve", "nope"], "no registered run 'nope'"),
    (["learning-curve", "ppo-c11-starts", "--episodes", "0"], "--episodes must be"),
    (["learning-curve", "ppo-c11-starts", "--runs", "/nonexistent"], "no finished run of ppo-c11-starts under"),
    # search
    (["tune-mpc", "--trials", "0"], "--trials must be"),
    (["tune-mpc", "--episodes", "-3"], "--episodes must be"),
    (["tune-mpc", "--control-mode", "torque"], "--control-mode: invalid choice"),
    (["tune-heuristic", "--trials", "0"], "--trials must be"),
    (["tune-heuristic", "--variant", "pause"], "--variant: invalid choice"),
    (["search", "torch-ppo"], "torch-ppo is not a registered SB3 run"),
    (["search", "ppo", "--trials", "0"], "--trials must be"),
    (["search", "ppo", "--grace-steps", "10", "--max-steps", "5"], "--grace-steps must be at most --max-steps"),
    (["search", "ppo", "--env-id", "Scara-C11-v9"], "--env-id: invalid choice"),
    # select
    (["select", "/nonexistent", "--out", "x"], "holds no config.json"),
    (["select"], "the following arguments are required"),
    # optimal
    (["optimal", "--wall-margin", "0.5"], "--wall-margin must be in"),
    (["optimal", "--write", "."], r"argument --write: \. is a folder, not a file"),
    (["optimal", "--wall-margin", "-1"], "--wall-margin must be in"),
    (["optimal", "--condition", "c11-starts"], "--condition: invalid choice"),
    (["optimal", "--start", "1", "2"], "--start: expected 3 arguments"),
    (["optimal", "--target", "a", "b", "c"], "--target: invalid float value"),
    # bench, the script itself
    (["bench", "--nonsense"], "unrecognized arguments: --nonsense"),
    ([], "the following arguments are required: COMMAND"),
    (["no-such-command"], "invalid choice: 'no-such-command'"),
]


def test_the_catalogue_covers_every_subcommand_with_over_a_hundred_mistakes():
    from agents.cli import build_parser

    commands = {argv[0] for argv, _ in MISTAKES if argv}
    subcommands = [a for a in build_parser()._actions if a.dest == "command"][0].choices
    assert set(subcommands) <= commands and len(MISTAKES) >= 100


def _refused_in_one_line(argv, says, capsys) -> None:
    """``run(argv)`` exits with status 2 and one line on stderr, no traceback, that matches ``says``."""
    with pytest.raises(SystemExit) as exit_:
        run(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "error:" in err and "Traceback" not in err, err
    assert re.search(says, err), err


FILE_MISTAKES = [
    # a folder argument that names an existing file, and files that hold the wrong JSON
    (["evaluate", "--out", "FILE"], "argument --out: FILE is a file, not a folder"),
    (["train", "torch-ppo", "--out", "FILE"], "argument --out: FILE is a file, not a folder"),
    (["torch-ppo", "--out", "FILE"], "--out: FILE is a file, not a folder"),
    (["compare", "--out", "FILE"], "argument --out: FILE is a file"),
    (["compare", "--cache", "FILE"], "argument --cache: FILE is a file"),
    (["compare", "--runs", "FILE"], "argument --runs: FILE is a file"),
    (["campaign", "--runs", "FILE"], "argument --runs: FILE is a file"),
    (["campaign", "--publish", "FILE", "--runs", "RUN"], "argument --publish: FILE is a file"),
    (["curves", "--cache", "FILE"], "argument --cache: FILE is a file"),
    (["sweep", "--run", "ppo", "--out", "FILE"], "argument --out: FILE is a file"),
    (["select", "RUN", "--out", "FILE"], "argument --out: FILE is a file"),
    (["datasets", "build", "scara/c11/random-v0", "--out", "FILE"], "argument --out: FILE is a file"),
    (["compare", "--runs", "RUN", "--only", "mpc", "--merge", "FILE"], "--merge: FILE is not JSON"),
    (["compare", "--runs", "RUN", "--only", "mpc", "--merge", "RUN/config.json"], "--merge: .* is not a comparison"),
    (["curves", "--only", "robust-shield", "--merge", "RUN"], "argument --merge: RUN is a folder"),
    (["curves", "--only", "robust-shield", "--merge", "RUN/summary.json"], "--merge: .* is not a curves.json"),
    (["datasets", "build", "scara/c11/expert-v0", "--runs", "FILE"], "argument --runs: FILE is a file"),
    (["torch-ppo", "--total-timesteps", "16", "--out", "RUN"], r"RUN/config\.json: holds a JSON list, not the object"),
    (["evaluate", "--policies", "bc:RUN"], r"RUN/config\.json: holds a JSON list"),
    (["evaluate", "--policies", "bc:TORCH"], r"TORCH: not a behaviour-cloning or DAgger run .*torchppo:DIR"),
    (["evaluate", "--policies", "bc:BROKEN"], r"BROKEN/config\.json: not JSON"),
    (["torch-ppo", "--total-timesteps", "16", "--out", "BROKEN"], r"BROKEN/config\.json: not JSON"),
]
"""as MISTAKES, in a working folder that holds FILE (a file), RUN (a folder with a config.json of [],
a summary.json and a model.pt), TORCH (a torch PPO run's config.json and a model.pt) and BROKEN (a
config.json cut short and a model.pt): each is refused in one line and the folder is left as it was"""


@pytest.mark.parametrize("argv, says", FILE_MISTAKES, ids=[" ".join(a) for a, _ in FILE_MISTAKES])
def test_a_path_of_the_wrong_kind_is_refused_in_one_line_and_nothing_changes(argv, says, capsys, tmp_path,
                                                                             monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "FILE").write_text("a file\n")
    (tmp_path / "RUN").mkdir()
    (tmp_path / "RUN" / "config.json").write_text("[]")
    (tmp_path / "RUN" / "summary.json").write_text("{}")
    (tmp_path / "RUN" / "model.pt").write_bytes(b"")
    (tmp_path / "TORCH").mkdir()
    (tmp_path / "TORCH" / "config.json").write_text('{"algo": "torch-ppo"}')
    (tmp_path / "TORCH" / "model.pt").write_bytes(b"")
    (tmp_path / "BROKEN").mkdir()
    (tmp_path / "BROKEN" / "config.json").write_text('{"algo": "bc", ')
    (tmp_path / "BROKEN" / "model.pt").write_bytes(b"")
    before = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    _refused_in_one_line(argv, says, capsys)
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == before  # nothing left behind


@pytest.mark.parametrize("argv, says", MISTAKES, ids=[" ".join(a) or "(nothing)" for a, _ in MISTAKES])
def test_a_mistake_ends_at_once_in_one_line_with_status_2(argv, says, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    started = time.perf_counter()
    _refused_in_one_line(argv, says, capsys)
    assert list(tmp_path.iterdir()) == []  # nothing left behind
    assert time.perf_counter() - started < 30.0  # refused before any work starts, not after


def test_a_set_value_written_as_1e_minus_4_is_a_number_not_text():
    from agents.cli import _yaml_value

    assert _yaml_value("1e-4") == 1e-4 and _yaml_value("1.0e-4") == 1e-4  # YAML 1.1 reads the first as text
    assert _yaml_value("[64, 64]") == [64, 64] and _yaml_value("true") is True and _yaml_value("fast") == "fast"


def test_bench_offpolicy_without_its_packages_names_what_to_install(monkeypatch, capsys):
    """--offpolicy needs sb3-contrib and sbx-rl, optional packages: one line naming the missing ones
    (whether or not they are installed here), before anything is trained."""
    import importlib.util

    found = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "sbx" else found(name, *a))
    if found("sb3_contrib") is None:
        _refused_in_one_line(["bench", "--offpolicy"], r"--offpolicy needs sb3-contrib and sbx-rl: pip install "
                                                       r"\"scara_gym\[offpolicy\]\" \(the offpolicy extra\)$", capsys)
    else:
        _refused_in_one_line(["bench", "--offpolicy"], r"--offpolicy needs sbx-rl: pip install "
                                                       r"\"scara_gym\[offpolicy\]\" \(the offpolicy extra\)$", capsys)


@pytest.mark.parametrize("bug", [KeyError("rows"), TypeError("unsupported operand"), ValueError("math domain error")])
def test_a_genuine_bug_shows_its_traceback_not_a_one_line_exit(bug, monkeypatch, capsys, tmp_path):
    """Only the project's UserError (raised by its checks) and the documented user errors end in
    one line: a KeyError, TypeError or ValueError from deeper down is a bug, and propagates."""
    import agents.cli

    def broken(*args, **kwargs):
        raise bug

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(agents.cli, "evaluate", broken)
    with pytest.raises(type(bug)) as raised:
        run(["evaluate", "--policies", "pd", "--episodes", "1"])
    assert raised.value is bug
    assert "error:" not in capsys.readouterr().err


def test_the_project_error_is_a_value_error_and_its_kinds_keep_their_builtin_classes():
    from scara_gym.model.checks import UserError, UserKeyError, UserTypeError, integer

    assert issubclass(UserError, ValueError) and issubclass(UserTypeError, TypeError)
    assert issubclass(UserKeyError, KeyError) and str(UserKeyError("no such block")) == "no such block"
    with pytest.raises(UserTypeError, match="seed must be an integer"):
        integer("seed", 1.5, 0)
    with pytest.raises(UserError, match="seed must be an integer >= 0, got -1"):
        integer("seed", -1, 0)
