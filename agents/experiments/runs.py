"""Training runs on disk: where a registered run lives, its lock, training it, publishing it.

Runs land in ``RUNS/ENV_ID/MODE/NAME/seedN`` (NAME: an entry of
`agents.experiments.registry.RUNS`). A finished run is skipped; an interrupted one
resumes from its snapshot or checkpoint, so a campaign (``scara-agents campaign``) can be
stopped and started again, across sessions. Each run is locked (``RUN/.lock``) by the process
training it (agents.files.exclusive, which every trainer takes too), and a worker passes over
runs that are finished or locked, so that workers started side by side share a list. `publish` copies a finished run with only what evaluating it
needs (the model, its normalizer, config and evaluation history; no snapshots, checkpoints or
logs), so that results can be committed (``results/runs``) and outlive the machine that
trained them.
"""

from __future__ import annotations

import shutil
import time
from pathlib import Path

from agents.algorithms.bc_config import BCConfig
from agents.algorithms.dagger_config import DAggerConfig
from agents.algorithms.sb3.hyperparams import load_hyperparams
from agents.algorithms.sb3.training import train as train_sb3, train_residual_ppo
from agents.algorithms.torch_ppo_config import Config
from agents.experiments.registry import RunSpec, spec
from agents.files import (
    PICKLE_FILES,
    POLICY_FILES,
    PUBLISHED_LIST,
    RunLocked,
    claim_run_folder,
    exclusive,
    json_record,
    publish_manifest,
    require_trusted,
    verify_digests,
    write_atomic,
    write_digests,
    write_json,
)
from scara_gym.benchmark.protocol import ENV_ID
from scara_gym.model.checks import UserError


def run_dir(runs: Path, env_id: str, control_mode: str, name: str, seed: int) -> Path:
    """Where seed ``seed`` of the registered run ``name`` lives under ``runs``."""
    return Path(runs) / env_id / control_mode / name / f"seed{seed}"


PUBLISHED = ("config.json", "summary.json", "model.zip", "model.pt", "vecnormalize.pkl", "evaluation.npz",
             "eval/evaluations.npz")
"""the files of a finished run that evaluating and plotting it need (the comparison)"""


def is_finished(run: Path) -> bool:
    """A run folder that holds a trained model (SB3's model.zip, or the torch PPO's model.pt
    with the summary.json it writes at the end: its model.pt is also a checkpoint)."""
    run = Path(run)
    return (run / "config.json").exists() and (
        (run / "model.zip").exists() or ((run / "model.pt").exists() and (run / "summary.json").exists()))


def publish(run: Path, dest: Path, listing: Path | None = None) -> Path:
    """Copy a finished run's PUBLISHED files from ``run`` to ``dest`` (made, or refreshed), and add
    its manifest to the list of published manifests ``listing`` (default: the PUBLISHED_LIST of
    the published runs' folder ``dest`` lies in, ``RUNS/ENV_ID/MODE/NAME/seedN``; never a file of
    the installed package): a run is published only from a trusted folder (this machine's own run)."""
    run, dest = Path(run), Path(dest)
    if not is_finished(run):
        raise UserError(f"{run} is not a finished run (no config.json with model.zip or model.pt)")
    # read once and checked: what is published is what was checked (pickle: only from a trusted folder)
    check = require_trusted if any((run / name).exists() for name in PICKLE_FILES) else verify_digests
    checked = check(run, wanted=POLICY_FILES)
    for name in PUBLISHED:
        if name in POLICY_FILES and name in checked:
            write_atomic(dest / name, checked.bytes(name))
        elif name not in POLICY_FILES and (run / name).exists():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(run / name, dest / name)
    write_digests(dest, POLICY_FILES)
    publish_manifest(dest, listing or dest.parents[3] / PUBLISHED_LIST)
    return dest


def hyperparams_of(name: str, env_id: str = ENV_ID, control_mode: str = "pd") -> dict:
    """What a run of the registered ``name`` trains with: its YAML block (SB3), or every field of
    the torch PPO Config it gets but the run's identity (env, mode, seed, folder)."""
    run = spec(name)
    if run.trainer == "sb3":
        return load_hyperparams(run.recipe, env_id, control_mode, run.variant)
    if run.trainer == "bc":
        config_class, identity, given = BCConfig, ("seed", "out"), {}
    else:
        config_class, identity = (DAggerConfig if run.trainer == "dagger" else Config), ("env_id", "control_mode",
                                                                                          "seed", "out")
        given = {"env_id": env_id, "control_mode": control_mode}
    fields = config_class(**{**run.fields, **given}).to_dict()
    for name_ in identity:
        fields.pop(name_)
    return fields


def train_run(name: str, out: Path, seed: int, env_id: str = ENV_ID, control_mode: str = "pd",
              total_timesteps: int | None = None, hyperparams: dict | None = None,
              command: str | None = None, randomize_target: bool = False, resume: bool = False,
              overwrite: bool = False) -> Path:
    """Train one run of the registered ``name`` into ``out``; with ``resume``, continue the run
    the folder holds (a finished one is found, and left as it is), with ``overwrite`` replace it;
    with neither, a folder that holds a run is refused (agents.files.claim_run_folder).
    hyperparams: what to train with (default: hyperparams_of). randomize_target: targets drawn
    per episode, for the ppo-residual runs (their YAML's "MODE-random" block); the other runs
    are registered for their own targets."""
    run = spec(name)
    if randomize_target and run.recipe != "ppo-residual":
        raise UserError(f"--randomize-target is for the ppo-residual runs (randomize_target=True); {name} is "
                        "registered for its own targets (the random-targets runs carry the tag)")
    if run.trainer == "bc":
        from agents.algorithms.bc import train as train_bc

        if control_mode != "pd":
            raise UserError(f"{name} clones a 'pd' mode dataset; train it with --control-mode pd")
        fields = dict(run.fields) if hyperparams is None else dict(hyperparams)
        if total_timesteps:  # its budget: Adam steps
            fields["steps"] = total_timesteps
        train_bc(BCConfig(**{**fields, "seed": seed, "out": str(out)}), overwrite=overwrite, resume=resume)
        return Path(out)
    if run.trainer == "dagger":
        from agents.algorithms.dagger import train as train_dagger

        fields = dict(run.fields) if hyperparams is None else dict(hyperparams)
        if total_timesteps:  # its budget: iterations
            fields["iterations"] = total_timesteps
        train_dagger(DAggerConfig.from_dict({**fields, "env_id": env_id, "control_mode": control_mode, "seed": seed,
                                             "out": str(out)}), overwrite=overwrite, resume=resume)
        return Path(out)
    if run.trainer == "torch-ppo":
        return _train_torch_ppo(run, Path(out), seed, env_id, control_mode, total_timesteps, hyperparams, resume,
                                overwrite)
    if run.recipe == "ppo-residual":
        return train_residual_ppo(control_mode, randomize_target, seed, total_timesteps, out, hyperparams,
                                  progress_bar=False, env_id=env_id, variant=run.variant, resume=resume,
                                  overwrite=overwrite)
    hyperparams = hyperparams_of(name, env_id, control_mode) if hyperparams is None else hyperparams  # its variant's block
    return train_sb3(run.sb3_algorithm, out, env_id, control_mode, seed, hyperparams=hyperparams,
                     total_timesteps=total_timesteps, command=command, resume=resume, overwrite=overwrite)


def _train_torch_ppo(run: RunSpec, out: Path, seed: int, env_id: str, control_mode: str,
                     total_timesteps: int | None, hyperparams: dict | None, resume: bool, overwrite: bool) -> Path:
    from agents.algorithms.torch_ppo import run_record, train

    fields = dict(run.fields) if hyperparams is None else dict(hyperparams)
    if total_timesteps:
        fields["total_timesteps"] = total_timesteps
    base = out.parent.parent / run.base / out.name if run.base is not None else None
    if base is not None:
        fields["init_from"] = str(base)
    config = Config.from_dict({**fields, "env_id": env_id, "control_mode": control_mode, "seed": seed,
                               "torch_threads": 1, "out": str(out)})  # checked before anything trains
    with exclusive(out):
        if is_finished(out) and not overwrite:  # a resumed, finished run would overwrite its summary
            claim_run_folder(out, run_record(config), resume, overwrite)  # this run, and resume asked for
            return out
        if base is not None:  # the base of a fine-tune: trained, continued or found finished
            train_run(run.base, base, seed, env_id, control_mode, total_timesteps, resume=True)
        train(config, resume=resume, overwrite=overwrite)
        if base is not None:
            record = json_record(out / "config.json")
            record["base_train_seconds"] = json_record(base / "config.json")["train_seconds"]
            write_json(out / "config.json", record)
            write_digests(out, POLICY_FILES)
    return out


def campaign(names: list[str], seeds: list[int], runs: Path, env_id: str = ENV_ID,
             control_mode: str = "pd", total_timesteps: int | None = None, shard: tuple[int, int] = (0, 1),
             publish_to: Path | None = None) -> list[Path]:
    """Every (seed, name) of the plan, or every ``shard[1]``-th from the ``shard[0]``-th: trained
    (or resumed, or found finished) where no other process holds its lock; with ``publish_to``,
    the finished ones published there instead of training. Returns the run folders done."""
    plan = [(name, seed) for seed in seeds for name in names][shard[0]::shard[1]]
    done = []
    for name, seed in plan:
        run = run_dir(runs, env_id, control_mode, name, seed)
        if publish_to is not None:
            if is_finished(run):
                done.append(publish(run, run_dir(publish_to, env_id, control_mode, name, seed)))
                print(f"{name} seed {seed}: published to {done[-1]}", flush=True)
            else:
                print(f"{name} seed {seed}: not finished, not published", flush=True)
            continue
        started = time.perf_counter()
        command = (f"scara-agents campaign {name} --seeds {seed} --env-id {env_id} --control-mode {control_mode} "
                   f"--runs {runs}")
        try:
            with exclusive(run):  # the run's folder, for the whole call (its trainer takes it again)
                out = train_run(name, run, seed, env_id, control_mode, total_timesteps, command=command,
                                resume=True)
        except RunLocked:
            print(f"{name} seed {seed}: trained by another process, passed over", flush=True)
            continue
        config = json_record(out / "config.json")
        print(f"{name} seed {seed}: {out} ({config['train_seconds']:.0f} s of training, "
              f"{time.perf_counter() - started:.0f} s in this call)", flush=True)
        done.append(out)
    return done
