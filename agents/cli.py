"""``scara-agents``: the agents' one console script.

    scara-agents evaluate --policies pd dec-continue:0.06 ppo:ppo_pd --episodes 100 --out runs/evaluate/pd
    scara-agents train ppo-residual --seed 0 --out runs/ppo_residual
    scara-agents torch-ppo --total-timesteps 2000000 --out runs/torch_ppo
    scara-agents campaign ppo sac td3 --seeds 0 1 2 3 4
    scara-agents compare --runs results/runs --episodes 30 --out runs/comparison
    scara-agents compare --runs results/runs --only mpc --merge docs/results/comparison.json --out docs/results
    scara-agents curves --runs results/runs --out runs/curves
    scara-agents sweep --run sac --grid learning_rate=0.0003,0.001
    scara-agents select RUN --out models/NAME
    scara-agents optimal --condition c11
    scara-agents bench
    scara-agents datasets build scara/c11/expert-v0 --episodes 1000

Each subcommand's ``--help`` says what it does. Outputs go under ``runs/`` in the working folder
unless ``--out`` says otherwise; the published runs (the repository's ``results/runs``) are found
where ``--runs`` or ``SCARA_GYM_PUBLISHED_RUNS`` says (agents.files.published_runs). A user's mistake ends in one line
``error: ...`` and exit status 2 (``--debug`` shows the traceback). SB3 model folders are
pickle: those neither shipped with the package nor written by a run on this machine load only
with ``--trust`` (agents.files.require_trusted).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from pathlib import Path

from agents.algorithms.bc_config import BCConfig
from agents.algorithms.dagger_config import DAggerConfig
from agents.algorithms.loaders import POLICY_SPECS, shipped_model
from agents.algorithms.progress import saved_to
from agents.algorithms.sb3.hyperparams import load_hyperparams, numba_threads
from agents.algorithms.torch_ppo_config import SEED_MAX, Config, parse_floats, parse_reward_weights
from agents.experiments import datasets, sweep as sweeps
from agents.experiments.checkpoints import select_checkpoint
from agents.experiments.comparison import ONLY_ROWS, SHIELDED, compare_in_parallel, merge_entries
from agents.experiments.curves import ONLY_CURVES, merge_curves, robustness_curves, write_curves
from agents.experiments.evaluation import COLUMNS, evaluate, learned_runs
from agents.experiments.learning_curves import learning_curve, run_folders
from agents.experiments.mpc_search import heuristic_controller, tune_controller, tune_mpc
from agents.experiments.registry import RUNS, spec
from agents.experiments.report import comparison_figures, comparison_markdown, evaluation_report, markdown_table
from agents.experiments.runs import campaign, hyperparams_of, train_run
from agents.experiments.search import SPACES, run_search
from agents.experiments.targets import target_checks
from agents.files import TRUST_ENV, RunLocked, write_atomic, write_json, write_json_lines
from agents.policies.optimal import CollocationConfig
from agents.policies.optimal.policy import solve_reference
from scara_gym import DEFAULT_PARAMS
from scara_gym.benchmark.protocol import CONDITIONS, ENV_ID, FIXED_SHIFTS, protocol_record
from scara_gym.extras import missing_extra_message, require
from scara_gym.model.checks import UserError
from scara_gym.registration import ENV_IDS

MODES = ("pd", "voltage")


def _add_trust(p) -> None:
    p.add_argument("--trust", action="store_true",
                   help="load SB3 model folders (pickle: loading one runs any code it holds) that were neither shipped "
                        "with the package nor written by a run on this machine; only for folders you trust")


def _folder(text: str) -> Path:
    """A folder argument: not empty (that would be the working folder, silently) and not an
    existing file (argparse names the argument in its one-line error)."""
    if not text:
        raise argparse.ArgumentTypeError("an empty path; give a folder ('.' for the working folder)")
    if Path(text).exists() and not Path(text).is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file, not a folder")
    return Path(text)


def _file(text: str) -> Path:
    """A file argument: not empty and not an existing folder."""
    if not text:
        raise argparse.ArgumentTypeError("an empty path; give a file")
    if Path(text).is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a folder, not a file")
    return Path(text)


def _folder_or_error(name: str, text: str) -> None:
    try:
        _folder(text)
    except argparse.ArgumentTypeError as error:
        raise UserError(f"{name}: {error}") from None


def _seeds(name: str, seeds) -> None:
    values = seeds if isinstance(seeds, list) else [seeds]
    if any(s is not None and not 0 <= s <= SEED_MAX for s in values):
        raise UserError(f"{name} must be {'integers' if isinstance(seeds, list) else 'an integer'} in [0, {SEED_MAX}], "
                        f"got {seeds}")


def _positive(name: str, value, allowed: str = ">= 1") -> None:
    if value is not None and value < 1:
        raise UserError(f"{name} must be {allowed}, got {value}")


# -- evaluate ---------------------------------------------------------------------------------
def _add_evaluate(sub) -> None:
    p = sub.add_parser("evaluate", help="run policies over the same fixed seeds; tables and plots",
                       description="Run policies over the same fixed seeds and write table.md, table.csv, "
                                   "tip_paths.png, wall_and_height.png (and NAME_results.json per shipped PPO).")
    p.add_argument("--policies", nargs="+", default=["pd", "dec-continue", "dec-restart"],
                   help=f"policy specs (agents.algorithms.loaders): {POLICY_SPECS}")
    p.add_argument("--env-id", choices=ENV_IDS, default=ENV_ID,
                   help=f"the id the episodes run on (default: the protocol's, {ENV_ID}; every policy, the "
                        "shipped PPO agents trained on Scara-C11-v0 included, is scored on it as it is)")
    p.add_argument("--control-mode", choices=MODES, default="pd")
    p.add_argument("--condition", choices=list(CONDITIONS), default="c11",
                   help="a condition of the evaluation protocol (scara_gym.benchmark.protocol), on its own seeds")
    p.add_argument("--episodes", type=int, default=None, help="default: the condition's own count")
    p.add_argument("--seed", type=int, default=None,
                   help="episode i uses seed + i (default: the condition's evaluation seeds)")
    p.add_argument("--out", type=_folder, default=Path("runs/evaluate"))
    _add_trust(p)
    p.set_defaults(handler=_evaluate)


def _evaluate(args, argv) -> list[dict]:
    if args.episodes is not None:
        _positive("--episodes", args.episodes)
    _seeds("--seed", args.seed)
    rows, traces = evaluate(args.policies, args.control_mode, args.condition, args.episodes, env_id=args.env_id,
                            seed=args.seed)
    models = {i: model for i, s in enumerate(args.policies) if (model := shipped_model(s)) is not None}
    evaluation_report(rows, traces, args.out, list(models.values()))
    for i, model_dir in models.items():  # the figures a model is tested against once shipped (its results.json)
        row = rows[i]
        write_json(args.out / f"{model_dir.name}_results.json", {
            "condition": args.condition, "seeds": rows[i]["seeds"],
            "success_rate": row["success rate"], "collision_rate": row["collision rate"],
            "mean_time_to_target": row["mean time to target [s]"],
            "worst_time_to_target": row["worst time to target [s]"],
            "episodes_outcomes": row["outcomes"], "command": "scara-agents " + " ".join(argv)})
    print(markdown_table(COLUMNS, rows))
    return rows


# -- train, torch-ppo, campaign ---------------------------------------------------------------
def _yaml_value(text: str):
    """A --set value as YAML reads it, but a number written as 1e-4 is a number (YAML 1.1, which
    PyYAML reads, takes only 1.0e-4)."""
    require("yaml")
    import yaml

    value = yaml.safe_load(text)
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            pass
    return value


def _config_value(field: dataclasses.Field, text: str):
    """A Config field's value from its command-line text, by the field's declared type."""
    kind = str(field.type)
    if kind == "bool":
        if text.lower() not in ("true", "false", "1", "0"):
            raise UserError(f"--{field.name.replace('_', '-')} takes true or false, got {text!r}")
        return text.lower() in ("true", "1")
    if kind.startswith("dict"):
        return parse_reward_weights(text)
    if kind == "tuple[str, ...]":  # names, comma-separated (DAggerConfig.conditions)
        return tuple(part.strip() for part in text.split(",") if part.strip())
    if kind.startswith("tuple"):
        return parse_floats(field.name, text, 3) if text else None
    if kind in ("str | None",):
        return text or None
    try:
        return {"int": int, "float": float, "str": str}[kind](text)
    except ValueError:
        raise UserError(f"--{field.name.replace('_', '-')} takes a number ({kind}), got {text!r}") from None


def _add_train(sub) -> None:
    p = sub.add_parser("train", help="train one registered run (--resume continues one)",
                       description="Train one seed of a registered run into --out; --resume continues the run "
                                   "a folder holds, --overwrite replaces it. Registered runs: " + ", ".join(RUNS))
    p.add_argument("name", choices=list(RUNS), metavar="NAME", help="a registered run (agents.experiments.registry)")
    p.add_argument("--env-id", choices=ENV_IDS, default=ENV_ID)
    p.add_argument("--control-mode", choices=MODES, default="pd")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=_folder, default=None, help="default: runs/NAME/seedN")
    p.add_argument("--total-timesteps", type=int, default=None, help="default: the run's budget")
    p.add_argument("--randomize-target", action="store_true",
                   help="ppo-residual runs: targets drawn per episode (the YAML's MODE-random block)")
    p.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                   help="hyperparameters to override (YAML block names, or torch PPO Config / BCConfig fields)")
    _add_run_folder_flags(p)
    _add_trust(p)
    p.set_defaults(handler=_train)


def _add_run_folder_flags(p) -> None:
    p.add_argument("--resume", action="store_true",
                   help="continue the run --out holds (an interrupted one from its snapshot or checkpoint; a finished "
                        "one: nothing to do)")
    p.add_argument("--overwrite", action="store_true",
                   help="train the run --out holds again from scratch (its files are removed)")


def _resume_or_overwrite(args) -> None:
    if args.resume and args.overwrite:
        raise UserError("--resume and --overwrite exclude each other: continue the run, or replace it")


FLAGGED = {"seed": "--seed", "out": "--out", "env_id": "--env-id", "control_mode": "--control-mode"}
"""the Config fields train sets from its own flags, not from --set"""


def _train(args, argv) -> Path:
    _resume_or_overwrite(args)
    _positive("--total-timesteps", args.total_timesteps)
    _seeds("--seed", args.seed)
    run = spec(args.name)
    overrides = {}
    for item in args.set:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UserError(f"--set takes NAME=VALUE items, got {item!r}")
        overrides[key] = value
    hyper = None
    if overrides or args.randomize_target:
        if run.trainer in ("torch-ppo", "bc", "dagger"):
            config_class, what = {"torch-ppo": (Config, "torch PPO Config"), "bc": (BCConfig, "BCConfig"),
                                  "dagger": (DAggerConfig, "DAggerConfig")}[run.trainer]
            fields = {f.name: f for f in dataclasses.fields(config_class) if f.name not in FLAGGED}
            flagged = sorted(set(overrides) & set(FLAGGED))
            if flagged:  # the command's own flags set these, and would silently replace them
                raise UserError(f"--set {flagged[0]}: give it as {FLAGGED[flagged[0]]}")
            unknown = sorted(set(overrides) - set(fields))
            if unknown:
                raise UserError(f"--set names {unknown}, which are not {what} fields; they are {sorted(fields)}")
            hyper = {**hyperparams_of(args.name, args.env_id, args.control_mode),
                     **{k: _config_value(fields[k], v) for k, v in overrides.items()}}
        else:
            hyper = load_hyperparams(run.recipe, args.env_id, args.control_mode, run.variant, args.randomize_target)
            unknown = sorted(set(overrides) - set(hyper))
            if unknown:
                raise UserError(f"--set names {unknown} that the YAML block lacks; it has {sorted(hyper)}")
            hyper.update({k: _yaml_value(v) for k, v in overrides.items()})
    out = args.out or Path("runs") / args.name / f"seed{args.seed}"
    folder = train_run(args.name, out, args.seed, args.env_id, args.control_mode, args.total_timesteps, hyper,
                       command="scara-agents " + " ".join(argv), randomize_target=args.randomize_target,
                       resume=args.resume, overwrite=args.overwrite)
    saved_to(folder)
    return folder


def _add_torch_ppo(sub) -> None:
    p = sub.add_parser("torch-ppo", help="the single-file PPO with every Config field as a flag",
                       description="Train the single-file PPO (agents.algorithms.torch_ppo); every field of its "
                                   "Config is a flag. reward weights as NAME=V,..., residual scale as A,B,C.")
    for f in dataclasses.fields(Config):
        flag = "--" + f.name.replace("_", "-")
        if str(f.type) == "bool":
            p.add_argument(flag, action=argparse.BooleanOptionalAction, default=f.default)
        else:
            p.add_argument(flag, default=None, metavar=str(f.type).upper().split(" ")[0].split("[")[0])
    p.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.pt")
    p.add_argument("--overwrite", action="store_true", help="train the run OUT holds again from scratch")
    p.set_defaults(handler=_torch_ppo)


def _torch_ppo(args, argv) -> dict:
    from agents.algorithms.torch_ppo import train

    values = {}
    for f in dataclasses.fields(Config):
        value = getattr(args, f.name)
        if value is not None:
            values[f.name] = value if isinstance(value, bool) else _config_value(f, value)
    _resume_or_overwrite(args)
    config = Config(**values)  # every field checked (Config.__post_init__)
    _folder_or_error("--out", config.out)
    threads = numba_threads()  # this machine's: not a Config check, a run may resume on a larger machine
    if config.device == "cpu" and config.env_threads > threads:
        raise UserError(f"--env-threads must be an integer in [1, {threads}] (numba's threads on this machine), "
                        f"got {config.env_threads}")
    if args.resume and not (Path(config.out) / "checkpoint.pt").exists():
        raise UserError(f"--resume: {config.out} holds no checkpoint.pt to resume from")
    summary = train(config, resume=args.resume, overwrite=args.overwrite)
    print(json.dumps(summary, indent=2))
    saved_to(config.out)
    return summary


def _shard(text: str) -> tuple[int, int]:
    try:
        shard, shards = (int(x) for x in text.split("/"))
    except ValueError:
        shard, shards = -1, 0
    if not 0 <= shard < shards:
        raise UserError(f"--shard must be K/N with 0 <= K < N, got {text!r}")
    return shard, shards


def _add_campaign(sub) -> None:
    p = sub.add_parser("campaign", help="every registered run over seeds, resumable, shareable between workers",
                       description="Train (or resume, or pass over finished or locked) every (seed, run) of the "
                                   "list into RUNS/ENV_ID/MODE/NAME/seedN, or publish the finished ones.")
    p.add_argument("names", nargs="*", metavar="NAME", default=[], help="registered runs (default: all): "
                   + ", ".join(RUNS))
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    p.add_argument("--env-id", choices=ENV_IDS, default=ENV_ID)
    p.add_argument("--control-mode", choices=MODES, default="pd")
    p.add_argument("--runs", type=_folder, default=Path("runs/baselines"))
    p.add_argument("--total-timesteps", type=int, default=None, help="default: each run's budget")
    p.add_argument("--shard", default="0/1", help="K/N: every N-th run, starting at the K-th (0-based)")
    p.add_argument("--publish", type=_folder, default=None, metavar="DEST",
                   help="copy the finished runs of the list, model and history only, to DEST (e.g. "
                        "results/runs) and list their manifests in DEST/published_manifests.txt, instead of "
                        "training")
    _add_trust(p)
    p.set_defaults(handler=_campaign)


def _campaign(args, argv) -> list[Path]:
    _seeds("--seeds", args.seeds)
    _positive("--total-timesteps", args.total_timesteps)
    for name in args.names:
        spec(name)
    if args.publish is not None and not args.runs.is_dir():  # nothing to publish: say so, not exit 0
        raise UserError(f"--runs: no folder {str(args.runs)!r} to publish from (the trained runs, ENV_ID/MODE/NAME/seedN)")
    return campaign(args.names or list(RUNS), args.seeds, args.runs, args.env_id, args.control_mode,
                    args.total_timesteps, _shard(args.shard), args.publish)


# -- compare, sweep, select -------------------------------------------------------------------
def _add_compare(sub) -> None:
    p = sub.add_parser("compare", help="learned vs classical vs optimal in every condition",
                       description="Every policy in every condition over the same seeds: comparison.json, "
                                   "comparison.md and the figures under --out.")
    p.add_argument("--runs", type=_folder, default=Path("runs/baselines"),
                   help="the folder of learned runs (ENV_ID/MODE/NAME/seedN)")
    p.add_argument("--conditions", nargs="+", choices=list(CONDITIONS), default=None,
                   help="default: every condition (with --merge: the merged comparison's)")
    p.add_argument("--episodes", type=int, default=None,
                   help="episodes per condition (default: each condition's own, with --merge the merged comparison's; "
                        "the C11 episode is one)")
    p.add_argument("--no-optimal", action="store_true", help="leave out the optimal reference")
    p.add_argument("--out", type=_folder, default=Path("runs/comparison"))
    p.add_argument("--only", nargs="+", choices=sorted(ONLY_ROWS), default=None, metavar="KIND",
                   help=f"evaluate only these kinds of row ({', '.join(sorted(ONLY_ROWS))}): after a change to "
                        "that policy alone; no figures")
    p.add_argument("--merge", type=_file, default=None, metavar="FILE",
                   help="with --only: a comparison.json whose other entries are kept; its rows of those kinds are "
                        "replaced (new ones put beside their kind), and the command recorded in its 'refreshed_by'")
    p.add_argument("--report-only", type=_file, default=None, metavar="FILE",
                   help="evaluate nothing: a comparison.json whose targets, and comparison.md beside it under "
                        "--out, are written anew from its entries (after a change to the report or the targets); "
                        "the command recorded in its 'reported_by'")
    p.add_argument("--jobs", type=int, default=1, help="processes evaluating conditions side by side")
    p.add_argument("--shield", nargs="*", default=list(SHIELDED), metavar="NAME",
                   help="learned runs to evaluate behind the shield as well (none: --shield)")
    p.add_argument("--cache", type=_folder, default=None, metavar="DIR",
                   help="keep learned runs' evaluations in DIR and reuse them (e.g. runs/compare-cache)")
    p.add_argument("--pilots", action="store_true", help="also the runs tagged 'pilot' (left out by default)")
    p.add_argument("--run-names", nargs="+", default=None, metavar="NAME",
                   help="only these registered runs of --runs (default: every one); e.g. with --only learned "
                        "--merge, to add a new run's rows to a published comparison")
    p.add_argument("--no-robust-shield", action="store_true",
                   help="leave out PD behind the robust shield in the shifted conditions (about 4 s per episode)")
    p.add_argument("--no-mpc", action="store_true", help="leave out the nonlinear MPC (about 10 s per episode) and the real-time MPC")
    p.add_argument("--no-mpc-latency", action="store_true",
                   help="leave out the MPC under its own latency (its 95th-percentile solve time as actuation delay; "
                        "about 10 s per episode)")
    p.add_argument("--no-decision-times", action="store_true",
                   help="leave out each row's compute per decision (its policy timed over the condition's first "
                        "episodes, never cached: on an idle machine, a few minutes in all)")
    _add_trust(p)
    p.set_defaults(handler=_compare)


def _report_only(args, argv) -> list[dict]:
    """compare --report-only FILE: the targets and the page of a published comparison, its entries as they are."""
    if args.only or args.merge:
        raise UserError("--report-only evaluates nothing: it takes no --only or --merge")
    try:
        data = json.loads(args.report_only.read_text())
    except FileNotFoundError:
        raise UserError(f"--report-only: no file {str(args.report_only)!r}") from None
    except (ValueError, UnicodeDecodeError) as error:
        raise UserError(f"--report-only: {args.report_only} is not JSON ({error})") from None
    if not isinstance(data, dict) or not isinstance(data.get("policies"), list):
        raise UserError(f"--report-only: {args.report_only} is not a comparison.json (it needs its 'policies')")
    entries = data["policies"]
    data = {**data, "targets": target_checks(entries), "reported_by": "scara-agents " + " ".join(argv)}
    args.out.mkdir(parents=True, exist_ok=True)
    write_json_lines(args.out / "comparison.json", data)
    report = comparison_markdown(entries)
    write_atomic(args.out / "comparison.md", report)
    print(report)
    return entries


def _compare(args, argv) -> list[dict]:
    if args.report_only is not None:
        return _report_only(args, argv)
    if args.episodes is not None:
        _positive("--episodes", args.episodes)
    _positive("--jobs", args.jobs)
    for flag, names in (("--shield", args.shield), ("--run-names", args.run_names or ())):
        unknown = [name for name in names if name not in RUNS]
        if unknown:
            raise UserError(f"{flag} names {unknown}, which are not registered runs; they are {sorted(RUNS)}")
    if not args.runs.is_dir():
        raise UserError(f"--runs: no folder {str(args.runs)!r} (the learned runs, ENV_ID/MODE/NAME/seedN; the "
                        "published ones are the repository's results/runs)")
    # the statistics run after hours of episodes, the MPC and the optimal replay need CasADi: a
    # missing extra is said before any episode
    require("rliable")
    if not (args.no_mpc and args.no_optimal):
        require("casadi")
    merged = _merged("--merge", args.merge, args.only, "comparison.json", ("policies", "conditions"))
    conditions = args.conditions or (list(merged["conditions"]) if merged else list(CONDITIONS))
    episodes = args.episodes
    if merged and episodes is None:  # the merged comparison's count per condition (its PD row's)
        episodes = {e["condition"]: e["episodes"] for e in merged["policies"] if e["name"] == "pd"}
    entries, traces = compare_in_parallel(args.runs, conditions, args.jobs, episodes=episodes,
                                          include_optimal=not args.no_optimal, cache=args.cache,
                                          shielded=tuple(args.shield), pilots=args.pilots,
                                          robust_shield=not args.no_robust_shield, include_mpc=not args.no_mpc,
                                          only=tuple(args.only or ()), decision_times=not args.no_decision_times,
                                          mpc_latency=not args.no_mpc_latency,
                                          run_names=None if args.run_names is None else tuple(args.run_names))
    command = "scara-agents " + " ".join(argv)
    if merged:
        entries = merge_entries(merged["policies"], entries, args.only)
        names = list(merged["conditions"]) + [c for c in conditions if c not in merged["conditions"]]
        data = {**merged, "conditions": protocol_record(names), "targets": target_checks(entries), "policies": entries}
        data.setdefault("refreshed_by", {}).update({kind: command for kind in args.only})
    else:
        data = {"env_id": ENV_ID, "command": command, "conditions": protocol_record(conditions),
                "targets": target_checks(entries), "policies": entries}
    args.out.mkdir(parents=True, exist_ok=True)
    write_json_lines(args.out / "comparison.json", data)
    report = comparison_markdown(entries)
    write_atomic(args.out / "comparison.md", report)
    if args.only:
        print(f"--only: the figures are not drawn (they need every entry's first episode); written to {args.out}")
    else:
        comparison_figures(entries, traces, learned_runs(args.runs), args.out)
    print(report)
    return entries


def _merged(flag: str, path: Path | None, only, name: str, keys: tuple[str, ...]) -> dict | None:
    """The published record ``path`` that ``flag`` names (None without it); UserError where it is
    given without --only or is not a record of that kind."""
    if path is None:
        return None
    if not only:
        raise UserError(f"{flag} needs --only KIND: the rows to evaluate and put in {path}")
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise UserError(f"{flag}: no file {str(path)!r}") from None
    except (ValueError, UnicodeDecodeError) as error:
        raise UserError(f"{flag}: {path} is not JSON ({error})") from None
    if not isinstance(data, dict) or any(key not in data for key in keys):
        raise UserError(f"{flag}: {path} is not a {name} (it needs {', '.join(keys)})")
    return data


def _add_learning_curve(sub) -> None:
    p = sub.add_parser("learning-curve", help="a learning-curve run's checkpoints scored at doubling budgets",
                       description="Every seed's checkpoints of a run tagged 'learning-curve' scored at its first checkpoint, twice it, "
                                   "... and its last on the tuning episodes of the condition it trains on "
                                   "(agents.experiments.learning_curves): NAME.json (summary, plateau, raw episodes) "
                                   "and NAME.png under --out.")
    p.add_argument("name", metavar="NAME", help="a registered run tagged 'learning-curve'")
    p.add_argument("--runs", type=_folder, default=Path("runs/curves"),
                   help="the folder of its runs (ENV_ID/MODE/NAME/seedN)")
    p.add_argument("--env-id", choices=ENV_IDS, default=ENV_ID, help="the id its runs trained on")
    p.add_argument("--episodes", type=int, default=50, help="tuning episodes per budget and seed")
    p.add_argument("--out", type=_folder, default=Path("runs/learning_curves"))
    p.add_argument("--merge", type=_file, default=None, metavar="FILE",
                   help="a NAME.json written before on the same episodes: its seeds not found under --runs are kept "
                        "(seeds trained in different sittings, their checkpoints gone)")
    p.set_defaults(handler=_learning_curve)


def _learning_curve(args, argv) -> dict:
    _positive("--episodes", args.episodes)
    if "learning-curve" not in spec(args.name).tags:
        raise UserError(f"{args.name} is not a learning-curve run; those are "
                        + ", ".join(n for n, r in RUNS.items() if "learning-curve" in r.tags))
    folders = run_folders(args.name, args.runs, args.env_id)
    if not folders:
        raise UserError(f"no finished run of {args.name} under {args.runs / args.env_id / 'pd' / args.name}; "
                        f"train one with scara-agents train {args.name} --out .../seedN")
    data = learning_curve(args.name, folders, args.episodes, args.out, merge=args.merge)
    print(f"{args.name}: plateau {data['plateau']}; written to {args.out}")
    return data


def _add_curves(sub) -> None:
    p = sub.add_parser("curves", help="robustness curves: success and time against shift and noise magnitude",
                       description="PD behind the shield, the tuned heuristic and the learned baselines at growing "
                                   "parameter shifts and sensor noise (agents.experiments.curves): curves.json and "
                                   "comparison_robustness.png under --out.")
    p.add_argument("--runs", type=_folder, default=None, help="the folder of learned runs (none: classical only)")
    p.add_argument("--episodes", type=int, default=20, help="episodes per point (and per seed)")
    p.add_argument("--robust-shield", action="store_true", help="also PD behind the robust shield (slow)")
    p.add_argument("--cache", type=_folder, default=None, metavar="DIR", help="as compare --cache")
    p.add_argument("--out", type=_folder, default=Path("runs/curves"))
    p.add_argument("--only", nargs="+", choices=sorted(ONLY_CURVES), default=None, metavar="KIND",
                   help=f"evaluate only these policies ({', '.join(sorted(ONLY_CURVES))}), to --merge them")
    p.add_argument("--merge", type=_file, default=None, metavar="FILE",
                   help="with --only: a curves.json whose other policies are kept, its episodes per point used; the "
                        "command is recorded in its 'refreshed_by' and the figure redrawn")
    _add_trust(p)
    p.set_defaults(handler=_curves)


def _curves(args, argv) -> dict:
    _positive("--episodes", args.episodes)
    if args.runs is not None and not args.runs.is_dir():
        raise UserError(f"--runs: no folder {str(args.runs)!r} (the learned runs, ENV_ID/MODE/NAME/seedN; the "
                        "published ones are the repository's results/runs)")
    if args.only and not args.merge:
        raise UserError("--only needs --merge FILE: the curves.json the policies are put in")
    merged = _merged("--merge", args.merge, args.only, "curves.json", ("episodes", "curves"))
    require("rliable")  # the curves' intervals, computed after the episodes: said before them
    if merged:
        data = merge_curves(merged, args.only, cache=args.cache)
        data.setdefault("refreshed_by", {}).update({kind: "scara-agents " + " ".join(argv) for kind in args.only})
    else:
        data = robustness_curves(args.runs, args.episodes, cache=args.cache, robust_shield=args.robust_shield)
        data["command"] = "scara-agents " + " ".join(argv)
    print(f"written: {', '.join(str(p) for p in write_curves(data, args.out))}")
    return data


def _add_search(sub) -> None:
    p = sub.add_parser("search", help="hyperparameter search of a standard SB3 run: Optuna through Ray Tune, ASHA",
                       description="Trials of a registered SB3 run's block with points Optuna proposes, scored at "
                                   "doubling rungs on the tuning episodes of the condition it trains on, stopped "
                                   "early by ASHA (agents.experiments.search): search.json, search.md, best.yml and "
                                   "rl_zoo.yml under --out; run again into a folder holding its search.json (rewritten at "
                                   "every rung) to resume, on any machine.")
    p.add_argument("name", metavar="NAME", help="a registered SB3 run (e.g. ppo-c11-starts)")
    p.add_argument("--trials", type=int, default=20)
    p.add_argument("--max-steps", type=int, default=1_000_000, help="a trial's budget (the last rung)")
    p.add_argument("--grace-steps", type=int, default=125_000, help="the first rung (ASHA's grace period)")
    p.add_argument("--episodes", type=int, default=20, help="tuning episodes a rung")
    p.add_argument("--env-id", choices=ENV_IDS, default=ENV_ID)
    p.add_argument("--control-mode", choices=MODES, default="pd")
    p.add_argument("--seed", type=int, default=0, help="the sampler's and the trials' training seed")
    p.add_argument("--cpus", type=int, default=None, help="trials at once (default: every core)")
    p.add_argument("--out", type=_folder, default=None, help="default: runs/search/NAME")
    p.set_defaults(handler=_search)


def _search(args, argv) -> dict:
    for flag in ("--trials", "--max-steps", "--grace-steps", "--episodes"):
        _positive(flag, getattr(args, flag[2:].replace("-", "_")))
    run = spec(args.name)
    if run.trainer != "sb3" or run.sb3_algorithm not in SPACES:
        raise UserError(f"{args.name} is not a registered SB3 run of {sorted(SPACES)}; those are "
                        + ", ".join(n for n, r in RUNS.items() if r.trainer == "sb3"))
    if args.grace_steps > args.max_steps:
        raise UserError(f"--grace-steps must be at most --max-steps ({args.max_steps}), got {args.grace_steps}")
    out = args.out or Path("runs/search") / args.name
    record = run_search(args.name, out, args.trials, args.max_steps, args.grace_steps, args.episodes, args.env_id,
                        args.control_mode, args.seed, args.cpus)
    print(f"{args.name}: {len(record['trials'])} trials, best {record['best']}; written to {out}")
    return record


def _add_tune_mpc(sub) -> None:
    p = sub.add_parser("tune-mpc", help="the real-time MPC tuned under the learned baselines' written rule",
                       description="Trials of the real-time MPC's horizon, margins and weights that Optuna proposes "
                                   "(the first: the published configuration), each scored once on the tuning "
                                   "episodes of c11-starts by the search's objective (agents.experiments.mpc_search): "
                                   "trials.jsonl, search.json, search.md and best.json under --out; run again into the "
                                   "same --out to go on.")
    p.add_argument("--trials", type=int, default=20)
    p.add_argument("--episodes", type=int, default=20, help="tuning episodes a trial")
    p.add_argument("--control-mode", choices=MODES, default="voltage")
    p.add_argument("--seed", type=int, default=0, help="the sampler's seed")
    p.add_argument("--out", type=_folder, default=Path("runs/search/mpc-rti"))
    p.set_defaults(handler=_tune_mpc)


def _add_tune_heuristic(sub) -> None:
    p = sub.add_parser("tune-heuristic", help="the dec heuristic's trigger distance tuned under the learned "
                                              "baselines' written rule",
                       description="Trials of the dec heuristic's trigger distance that Optuna proposes (the first: "
                                   "the distance the comparison uses), each scored once on the tuning episodes of "
                                   "c11-starts by the search's objective (agents.experiments.mpc_search): "
                                   "trials.jsonl, search.json, search.md and best.json under --out; run again into the "
                                   "same --out to go on.")
    p.add_argument("--variant", choices=("continue", "restart"), default="continue")
    p.add_argument("--trials", type=int, default=20)
    p.add_argument("--episodes", type=int, default=20, help="tuning episodes a trial")
    p.add_argument("--seed", type=int, default=0, help="the sampler's seed")
    p.add_argument("--out", type=_folder, default=None, help="default: runs/search/dec-VARIANT")
    p.set_defaults(handler=_tune_heuristic)


def _tune_heuristic(args, argv) -> dict:
    for flag in ("--trials", "--episodes"):
        _positive(flag, getattr(args, flag[2:]))
    out = args.out or Path("runs/search") / f"dec-{args.variant}"
    record = tune_controller(heuristic_controller(args.variant), out, args.trials, args.episodes, "pd", args.seed)
    print(f"dec-{args.variant}: {record['trials_run']} trials, best {record['best']}; written to {out}")
    return record


def _tune_mpc(args, argv) -> dict:
    for flag in ("--trials", "--episodes"):
        _positive(flag, getattr(args, flag[2:]))
    require("casadi")
    record = tune_mpc(args.out, args.trials, args.episodes, args.control_mode, args.seed)
    print(f"mpc-rti: {record['trials_run']} trials, best {record['best']}; written to {args.out}")
    return record


def _add_sweep(sub) -> None:
    p = sub.add_parser("sweep", help="seeds x hyperparameter grids on Ray Tune",
                       description="Train and evaluate every (grid point, seed) of a registered run as a Ray Tune "
                                   "trial; sweep.json and sweep.md under --out.")
    p.add_argument("--run", choices=list(RUNS), metavar="NAME", required=True, help="a registered run")
    p.add_argument("--env-id", choices=ENV_IDS, default=ENV_ID)
    p.add_argument("--control-mode", choices=MODES, default="pd")
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    p.add_argument("--grid", nargs="*", default=[], metavar="NAME=V1,V2",
                   help="hyperparameter values to cross (names of the run's YAML block or Config)")
    p.add_argument("--condition", choices=list(CONDITIONS), default="c11", help="the evaluation condition")
    p.add_argument("--episodes", type=int, default=100)
    p.add_argument("--total-timesteps", type=int, default=None, help="default: the run's budget")
    p.add_argument("--out", type=_folder, default=Path("runs/sweeps/default"))
    p.add_argument("--address", default=None, help="an existing Ray cluster (default: a local runtime)")
    p.add_argument("--cpus-per-trial", type=float, default=1.0)
    p.add_argument("--max-concurrent", type=int, default=None,
                   help="trials at once (default: as many as the CPUs allow); 1 leaves the other cores free")
    p.add_argument("--max-failures", type=int, default=2, help="retries of a failed trial")
    p.add_argument("--publish", type=_folder, default=None, metavar="DEST",
                   help="copy the finished trials' runs to DEST/ENV_ID/MODE/NAME/seedN (e.g. results/runs)")
    p.set_defaults(handler=_sweep)


def _sweep(args, argv) -> list[dict]:
    _seeds("--seeds", args.seeds)
    _positive("--episodes", args.episodes)
    _positive("--total-timesteps", args.total_timesteps)
    _positive("--max-concurrent", args.max_concurrent)
    if not args.cpus_per_trial > 0:
        raise UserError(f"--cpus-per-trial must be > 0, got {args.cpus_per_trial}")
    if args.max_failures < 0:
        raise UserError(f"--max-failures must be >= 0, got {args.max_failures}")
    grid = sweeps.parse_grid(args.grid)
    entries = sweeps.run_sweep(args.run, args.env_id, args.control_mode, args.seeds, grid, args.out, args.condition,
                               args.episodes, args.total_timesteps, args.address, args.cpus_per_trial,
                               args.max_failures, max_concurrent=args.max_concurrent)
    print((args.out / "sweep.md").read_text())
    if args.publish is not None:
        sweeps.publish_trials(args.run, args.env_id, args.control_mode, args.seeds, grid, args.out, args.publish)
    return entries


def _add_select(sub) -> None:
    p = sub.add_parser("select", help="ship the fastest clean checkpoint of an SB3 PPO run",
                       description="Evaluate every checkpoint of an SB3 PPO run and copy the fastest that "
                                   "succeeds in every episode without a collision to --out.")
    p.add_argument("run_dir", type=Path, metavar="RUN", help="a run folder with checkpoints/ (SB3 PPO)")
    p.add_argument("--out", type=_folder, required=True)
    p.add_argument("--episodes", type=int, default=5)
    p.add_argument("--seed", type=int, default=5000)
    _add_trust(p)
    p.set_defaults(handler=_select)


def _select(args, argv) -> dict:
    _positive("--episodes", args.episodes)
    _seeds("--seed", args.seed)
    if not (args.run_dir / "config.json").exists() or not list(args.run_dir.glob("checkpoints/ppo_*_steps.zip")):
        raise UserError(f"RUN: {str(args.run_dir)!r} holds no config.json with checkpoints/ppo_N_steps.zip")
    return select_checkpoint(args.run_dir, args.out, args.episodes, args.seed)


# -- optimal, bench ---------------------------------------------------------------------------
def _add_optimal(sub) -> None:
    p = sub.add_parser("optimal", help="the minimum-time reference by direct collocation (CasADi)",
                       description="Solve both minimum-time problems (free and held voltages) and replay the held "
                                   "solution in the environment; --write keeps it as a shipped solution file.")
    p.add_argument("--start", nargs=3, type=float, default=list(DEFAULT_PARAMS.task.start))
    p.add_argument("--target", nargs=3, type=float, default=list(DEFAULT_PARAMS.task.target))
    p.add_argument("--write", type=_file, default=None,
                   help="write the solutions as JSON here (the shipped file: agents/optimal_solutions/c11.json)")
    shifts = ["c11", *FIXED_SHIFTS]
    p.add_argument("--condition", choices=shifts, default="c11",
                   help="a fixed parameter shift of the protocol; default c11, the C11 parameters")
    p.add_argument("--wall-margin", type=float, default=CollocationConfig.wall_margin,
                   help="m, distance the held solution keeps from the wall plane while below h_obs (default "
                        "%(default)s; a wider one gives the torch PPO's demo resets states with slack)")
    p.add_argument("--verbose", action="store_true")
    p.set_defaults(handler=_optimal)


def _optimal(args, argv) -> dict:
    params = DEFAULT_PARAMS.replace(CONDITIONS[args.condition].params)
    if not 0.0 <= args.wall_margin < params.obstacle.critical_distance:
        raise UserError(f"--wall-margin must be in [0, {params.obstacle.critical_distance}) m (the critical band), "
                        f"got {args.wall_margin}")
    record = solve_reference(args.start, args.target, params, args.wall_margin, args.verbose)
    data = {**record, "condition": args.condition, "overrides": dict(CONDITIONS[args.condition].params),
            "command": "scara-agents optimal" + (f" --start {' '.join(map(str, args.start))}"
                                                 f" --target {' '.join(map(str, args.target))}"
                                                 f" --condition {args.condition}")
                       + (f" --wall-margin {args.wall_margin}" if args.wall_margin != CollocationConfig.wall_margin
                          else "")}
    if args.write:
        args.write.parent.mkdir(parents=True, exist_ok=True)
        args.write.write_text(json.dumps(data, indent=1))
    return data


def _add_bench(sub) -> None:
    p = sub.add_parser("bench", help="training speed: the single-file PPO beside SB3's (and HER, GPU)",
                       description="End-to-end PPO training steps/s on the CPU, side by side with SB3's PPO; "
                                   "--gpu adds the GPU PPO where a CUDA device is usable, --her the HER buffer.")
    p.add_argument("--quick", action="store_true", help="small budgets (seconds), for a smoke test")
    p.add_argument("--her", action="store_true", help="also ms per SAC + HER update, SB3's buffer and ours")
    p.add_argument("--gpu", action="store_true", help="also the GPU PPO (a CUDA device and the cuda extra)")
    p.add_argument("--env-ids", nargs="+", choices=ENV_IDS, default=[ENV_ID],
                   help=f"the ids the CPU PPO trains on, in turn in one sitting (default: {ENV_ID})")
    p.add_argument("--offpolicy", action="store_true",
                   help="also off-policy steps/s of SB3 SAC/TD3, sb3-contrib TQC and sbx-rl SAC/TD3/TQC/CrossQ, "
                        "interleaved, on the first --env-ids, every trainer on one thread (the offpolicy "
                        "extra: pip install \"scara_gym[offpolicy]\")")
    p.set_defaults(handler=_bench)


def _bench(args, argv) -> str:
    from agents.experiments import bench as agents_bench

    missing = agents_bench.offpolicy_missing() if args.offpolicy else []
    if missing:
        raise UserError(f"--offpolicy needs {' and '.join(missing)}: pip install \"scara_gym[offpolicy]\" (the offpolicy extra)")
    return agents_bench.main(args.quick, args.her, args.gpu, tuple(args.env_ids), args.offpolicy)


def _add_datasets(sub) -> None:
    p = sub.add_parser("datasets", help="offline datasets in Minari's format (the minari extra)",
                       description="Build the offline datasets (agents.experiments.datasets: scara/<task>/<tier>-vN, "
                                   "-v0 on Scara-C11-v1, -v1 on Scara-C11-v2) into Minari's data folder "
                                   "(MINARI_DATASETS_PATH, else ~/.minari/datasets) or --out; 'list' names them, "
                                   "'build all' builds every one of --version (keeping those built before), "
                                   "'replay' steps a built dataset's actions again and checks every bit.")
    p.add_argument("action", choices=("build", "list", "replay"))
    p.add_argument("name", nargs="?", help="a dataset id (scara-agents datasets list), or 'all' with build")
    p.add_argument("--episodes", type=int, help="episodes per dataset (default: its own count; medium-replay: "
                                                "all the medium run's training episodes)")
    p.add_argument("--out", type=_folder, help="the datasets' folder (default: Minari's)")
    p.add_argument("--runs", type=_folder, default=None,
                   help="the published runs the experts are picked from (default: $SCARA_GYM_PUBLISHED_RUNS, else the "
                        "clone's results/runs; the random and medium tiers record the published expert without them)")
    p.add_argument("--summary", type=_file, help="with 'all': write the datasets' sizes and build times here (JSON)")
    p.add_argument("--version", choices=tuple(datasets.DATASET_VERSIONS), default=datasets.LATEST_DATASET_VERSION,
                   help="with 'all': the datasets' version (default: the latest, on the protocol's id)")
    p.add_argument("--tiers", nargs="+", choices=(*datasets.TIERS, datasets.ORACLE_TIER), default=None,
                   help="with 'all': only these tiers (default: every one)")
    p.add_argument("--jobs", type=int, default=1, help="worker processes for the oracle tier's episodes (default 1)")
    p.set_defaults(handler=_datasets)


def _datasets(args, argv):
    if args.action == "list":
        for name, spec in datasets.DATASETS.items():
            print(f"{name}  ({spec.episodes} episodes)")
        return list(datasets.DATASETS)
    if not args.name:
        raise UserError(f"datasets {args.action} needs a dataset id{' or ' + repr('all') if args.action == 'build' else ''} "
                        "(scara-agents datasets list names them)")
    _positive("--episodes", args.episodes)
    _positive("--jobs", args.jobs)
    require("minari")
    if args.action == "replay":
        datasets.get_dataset(args.name)  # an unknown id: the list of ids
        if args.out is not None:
            os.environ["MINARI_DATASETS_PATH"] = str(args.out.resolve())
        replayed = datasets.replay(datasets.load(args.name), args.episodes)
        print(f"{args.name}: {replayed} episodes replayed bit for bit")
        return replayed
    if args.name == "all":
        return datasets.build_all(args.episodes, args.out, args.runs, summary=args.summary, version=args.version,
                                  tiers=args.tiers, jobs=args.jobs)
    return datasets.build(args.name, args.episodes, args.out, args.runs, jobs=args.jobs)


class _Parser(argparse.ArgumentParser):
    """argparse's parser with its errors in one line (``PROG: error: ...``, exit status 2), as
    the subcommands' own errors are; ``--help`` shows the usage."""

    def error(self, message: str):
        print(f"{self.prog}: error: {message} (see {self.prog} --help)", file=sys.stderr)
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="scara-agents", description="The agents of scara_gym: evaluate, train, compare, sweep.")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (_add_evaluate, _add_train, _add_torch_ppo, _add_campaign, _add_compare, _add_curves,
                _add_learning_curve, _add_search, _add_tune_mpc, _add_tune_heuristic, _add_sweep,
                _add_select, _add_optimal, _add_bench, _add_datasets):
        add(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """The console script: runs one subcommand; 0, or exit status 2 for a user's mistake."""
    run(argv)
    return 0


def run(argv: list[str] | None = None):
    """Run one subcommand and return what it returns (its rows, entries, run folder, ...); a
    user's mistake exits with status 2 and one line on stderr."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    trusted_before = os.environ.get(TRUST_ENV)
    if getattr(args, "trust", False):  # for this command and the worker processes it starts
        os.environ[TRUST_ENV] = "1"
    try:
        return _run_handler(args, argv)
    finally:
        if trusted_before is None:
            os.environ.pop(TRUST_ENV, None)
        else:
            os.environ[TRUST_ENV] = trusted_before


USER_ERRORS = (UserError, FileNotFoundError, RunLocked)
"""what ends a subcommand in one line and exit status 2 (beside argparse's own and a missing
extra's ModuleNotFoundError): the project's UserError, raised by its checks; a path that is not
there; a run folder another process is writing. Anything else is a bug and shows its traceback."""


def _run_handler(args, argv):
    try:
        return args.handler(args, argv)
    except ImportError as error:  # an optional module of an extra: one line naming the extra
        message = missing_extra_message(error.name) if isinstance(error, ModuleNotFoundError) else None
        if message is None or args.debug:
            raise
        print(f"scara-agents {args.command}: error: {message}", file=sys.stderr)
        raise SystemExit(2) from None
    except USER_ERRORS as error:
        if args.debug:
            raise
        print(f"scara-agents {args.command}: error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
