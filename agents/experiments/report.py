"""The one report writer: Markdown tables and figures for evaluations, comparisons and sweeps."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from agents.experiments.entries import is_zero_shot, row_of, run_tags
from agents.experiments.evaluation import COLUMNS, DECISION_EPISODES
from agents.experiments.registry import RUNS, trained_for
from agents.experiments.runs import hyperparams_of
from agents.experiments.statistics import episodes_of, interval_estimates, iqm, rate_claim, rate_text
from agents.experiments.targets import target_checks
from agents.files import write_atomic
from scara_gym import DEFAULT_PARAMS
from scara_gym.benchmark.episodes import BAND_NAMES
from scara_gym.benchmark.protocol import CONDITIONS, ENV_ID


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path, written: list[Path]) -> None:
    """The figure as a 256-colour PNG, atomically: a plot of a few lines and bands loses nothing
    visible in a palette, and the file is a third of the full-colour one (the published results
    stay small enough to keep in the repository)."""
    plt = _pyplot()
    from PIL import Image  # matplotlib's own dependency

    fig.tight_layout()
    rendered = io.BytesIO()
    fig.savefig(rendered, dpi=110, format="png")
    plt.close(fig)
    palette = io.BytesIO()
    Image.open(rendered).convert("RGB").quantize(colors=256).save(palette, format="png", optimize=True)
    write_atomic(path, palette.getvalue())
    written.append(path)


def _cell(value) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, (int, np.integer)):
        return str(value)
    return "-" if np.isnan(value) else f"{value:.4f}"


def markdown_table(columns, rows: list[dict]) -> str:
    """A Markdown table of ``rows`` (dicts) in ``columns``: numbers with four decimals, NaN as "-"."""
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(_cell(row[c]) for c in columns) + " |" for row in rows]
    return "\n".join(lines)


def tip_paths(traces: dict[str, list[np.ndarray]], path: Path, title: str, figsize=(6.5, 6),
              legend_size: int = 8) -> Path:
    """The tool tip's paths in the plane beside the wall and its critical band (traces of
    scara_gym.benchmark.episodes.run_episode, a list per label; "optimal" drawn thick and black)."""
    plt = _pyplot()
    obstacle = DEFAULT_PARAMS.obstacle
    fig, ax = plt.subplots(figsize=figsize)
    ax.axvspan(obstacle.x_position - obstacle.critical_distance, obstacle.x_position + obstacle.critical_distance,
               color="0.88")
    ax.axvline(obstacle.x_position, color="k", lw=2, label="wall (x_obs)")
    for (label, runs), color in zip(traces.items(), plt.cm.tab10.colors):
        optimal = label == "optimal"
        for k, trace in enumerate(runs):
            ax.plot(trace[:, 1], trace[:, 2], color="k" if optimal else color, lw=2.5 if optimal else 1.1,
                    label=label if k == 0 else None)
    ax.set(xlabel="x [m]", ylabel="y [m]", title=title, aspect="equal")
    ax.legend(fontsize=legend_size)
    written: list[Path] = []
    _save(fig, path, written)
    return path


def evaluation_report(rows: list[dict], traces: dict, out: Path, model_dirs: list[Path]) -> list[Path]:
    """``scara-agents evaluate``'s outputs under ``out``: table.md, table.csv, tip_paths.png,
    wall_and_height.png and, for models with evaluation logs, learning_curves.png."""
    plt = _pyplot()
    out.mkdir(parents=True, exist_ok=True)
    (out / "table.md").write_text(markdown_table(COLUMNS, rows) + "\n")
    with open(out / "table.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    written = [out / "table.md", out / "table.csv",
               tip_paths(traces, out / "tip_paths.png", "Tool-tip paths (first episodes)")]
    obs = DEFAULT_PARAMS.obstacle
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for (name, runs), color in zip(traces.items(), plt.cm.tab10.colors):
        trace = runs[0]
        top.plot(trace[:, 0], trace[:, 3], color=color, label=name)
        bottom.plot(trace[:, 0], trace[:, 5], color=color, label=name)
    top.axhspan(-obs.critical_distance, obs.critical_distance, color="0.88")
    top.axhline(0, color="k", lw=1)
    top.set(ylabel="x_tip - x_obs [m]", title="Distance to the wall and height (first episode; seed Fig. 4, 6, 7)")
    bottom.axhline(obs.height, color="k", lw=1, label="h_obs")
    bottom.set(xlabel="t [s]", ylabel="q3 [m]")
    top.legend(fontsize=8)
    _save(fig, out / "wall_and_height.png", written)

    curves = [(d, np.load(d / "eval" / "evaluations.npz")) for d in model_dirs
              if (d / "eval" / "evaluations.npz").exists()]
    if curves:
        fig, ax = plt.subplots(figsize=(7, 4))
        for model_dir, data in curves:
            mean = data["results"].mean(axis=1)
            ax.plot(data["timesteps"], mean, label=model_dir.name)
        ax.set(xlabel="environment steps", ylabel="mean evaluation return", title="PPO learning curves")
        ax.legend()
        _save(fig, out / "learning_curves.png", written)
    return written


def comparison_markdown(entries: list[dict]) -> str:
    """The comparison's report: the targets, the verdicts, the overview and one table per condition."""
    met = {True: "yes", False: "**no**", None: "-"}
    rows = [{"target": c["target"], "met": met[c["met"]], "reached": c["reached"]} for c in target_checks(entries)]
    lines = ["#### Targets", "", markdown_table(("target", "met", "reached"), rows), ""]
    return ("\n".join(lines) + "\n" + verdicts(entries) + "\n" + overview(entries) + "\n"
            + learned_rows(entries) + "\n" + condition_tables(entries))


def tuning_of(tags) -> str:
    """How a learned run's settings were chosen, from its registry tags."""
    if "tuned" in tags:
        return "searched: the best of its algorithm's hyperparameter search (record under results/search/)"
    if "distilled" in tags:
        return "distilled from the real-time MPC (DAgger); the network's settings hand-set"
    if "offline" in tags:
        return "behaviour cloning of a dataset; hand-set"
    if "engineered" in tags or "constrained" in tags or "interface-ablation" in tags:
        return "hand-set in pilots (docs/experiments.md), not searched"
    return "untuned: its implementation's defaults (RL Zoo's for SB3's algorithms)"


def budget_of(run: str, env_id: str, control_mode: str) -> str:
    """A registered run's training budget in environment steps (its block's or Config's), as text."""
    if run not in RUNS:
        return "-"
    hyper = hyperparams_of(run, env_id, control_mode)
    steps = hyper.get("n_timesteps", hyper.get("total_timesteps"))
    if steps is None:
        return "-"
    base = RUNS[run].base
    return f"{int(steps):,} steps" + (f" after {base}'s" if base else "")


def learned_rows(entries: list[dict]) -> str:
    """What each learned row had: its seeds, the draws it trained on, its budget and recipe (the
    registry's description) and how its settings were chosen (issue 58 item 9: every claim names
    the budget and tuning of the rows it rests on)."""
    seen = {}
    for e in entries:
        if e["kind"] in ("learned", "offline") and e.get("run") and e["run"] not in seen:
            seen[e["run"]] = e
    rows = []
    for run, e in seen.items():
        tags = frozenset(e.get("tags") or ())
        draws = sorted(trained_for(tags))
        rows.append({"run": run, "seeds": ",".join(str(s) for s in e.get("seeds") or ()) or "-",
                     "trained on": ", ".join(f"{d} draws" for d in draws) or "the C11 episode's start",
                     "budget": budget_of(run, e.get("env_id", ENV_ID), e["control_mode"]),
                     "recipe": RUNS[run].description if run in RUNS else "-", "tuning": tuning_of(tags)})
    if not rows:
        return ""
    return ("#### Learned rows: what each had (seeds, training draws, budget in environment steps, recipe, how "
            "its settings were chosen)\n\n"
            + markdown_table(("run", "seeds", "trained on", "budget", "recipe", "tuning"), rows) + "\n")


CLASSICAL_KINDS = ("pd", "heuristic", "mpc", "mpc-rti")
"""the kinds a verdict counts as classical controllers (the optimal open-loop replay is a reference, not one)"""


def _rank(e: dict) -> tuple:
    """Best first: clean (every episode a success, none a collision), then fewer collisions, more
    successes, less time."""
    clean = e["success_rate"] == 1.0 and e["collision_rate"] == 0.0
    return (not clean, e["collision_rate"], -e["success_rate"], e["time_iqm"])


def _verdict_cell(e: dict) -> str:
    return (f"{e['name']}: {rate_text(e['success_rate'])} / {rate_text(e['collision_rate'])}, "
            f"{e['time_iqm']:.3f} s, {e['energy_mean']:.0f} J; collisions "
            f"{rate_claim(e['collision_rate'], episodes_of(e))}")


def verdicts(entries: list[dict]) -> str:
    """Per condition: the best classical and the best learned policy without a shield (ranked by
    _rank: clean first, then collisions, success, time), which wins by how much, and the best
    policy behind a shield."""
    lines = ["#### Verdicts: the best classical and the best learned policy without a shield, per condition "
             "(success / collisions, time IQM, energy; the episodes with a collision of all its episodes, with "
             "their 95 % Clopper-Pearson interval, seeds pooled), and the best behind a shield; a learned policy "
             "counts only where it is not zero-shot (in c11-starts, random-targets and random-shifts: trained on "
             "that condition's draws)", "",
             "| condition | best classical | best learned | verdict | best behind a shield |", "|---|---|---|---|---|"]
    for name, c, ell, side, by, shielded in _verdict_rows(entries):
        best_shielded = _verdict_cell(shielded) if shielded else "-"
        lines.append(f"| {name} | {_verdict_cell(c)} | {_verdict_cell(ell)} | {side} wins: {by} | {best_shielded} |")
    return "\n".join(lines) + "\n"


def _verdict_rows(entries: list[dict]):
    """Per condition with both: (condition, best classical, best learned (not zero-shot), the
    winning side, by how much, the best shielded entry or None), each ranked by _rank."""
    for name in dict.fromkeys(e["condition"] for e in entries):
        here = [e for e in entries if e["condition"] == name]
        classical = sorted((e for e in here if e["kind"] in CLASSICAL_KINDS and not e.get("shielded")), key=_rank)
        learned = sorted((e for e in here if e["kind"] == "learned" and not e.get("shielded") and not is_zero_shot(e)),
                         key=_rank)
        shielded = sorted((e for e in here if e.get("shielded")), key=_rank)
        if not classical or not learned:
            continue
        c, ell = classical[0], learned[0]
        winner, other = (c, ell) if _rank(c) <= _rank(ell) else (ell, c)
        if _rank(winner)[:3] == _rank(other)[:3]:
            by = f"{other['time_iqm'] - winner['time_iqm']:.3f} s faster"
        else:
            by = (f"collisions {rate_text(winner['collision_rate'])} vs {rate_text(other['collision_rate'])}, "
                  f"success {rate_text(winner['success_rate'])} vs {rate_text(other['success_rate'])}")
        yield name, c, ell, "classical" if winner is c else "learned", by, (shielded[0] if shielded else None)


def _short_cell(e: dict) -> str:
    count = len(e.get("seeds") or ())
    seeds = f", {count} seed{'s' if count > 1 else ''}" if count else ""
    rates = "" if _rank(e)[0] is False else f", {rate_text(e['success_rate'])} / {rate_text(e['collision_rate'])}"
    return f"{e['name']} ({e['time_iqm']:.3f} s{rates}{seeds})"


def verdict_summary(entries: list[dict], conditions: tuple[str, ...] | None = None) -> str:
    """The verdicts in brief (the README's, over its headline conditions): per condition, the best
    classical controller and the best learned policy without a shield (not zero-shot), and which
    wins by how much; the full verdicts, with intervals, and each learned row's budget and tuning
    are in comparison.md."""
    lines = ["| condition | best classical (IQM time) | best learned, no shield | verdict |", "|---|---|---|---|"]
    for name, c, ell, side, by, _ in _verdict_rows(entries):
        if conditions is not None and name not in conditions:
            continue
        lines.append(f"| {name} | {_short_cell(c)} | {_short_cell(ell)} | {side}: {by} |")
    return "\n".join(lines) + "\n"


def curve_figure(data: dict, path: Path) -> Path:
    """Success rate and time to target (IQM) against each curve's factor, one column per curve
    (agents.experiments.curves' data)."""
    plt = _pyplot()
    curves = data["curves"]
    fig, axes = plt.subplots(2, len(curves), figsize=(4 * len(curves), 6.5), squeeze=False)
    for column, (curve, points) in enumerate(curves.items()):
        for (label, row), color in zip(points["policies"].items(), plt.cm.tab10.colors):
            axes[0, column].plot(points["factors"], row["success"], "o-", color=color, label=label)
            axes[1, column].plot(points["factors"], row["time_iqm"], "o-", color=color, label=label)
        axes[0, column].set(title=curve, ylabel="success rate", ylim=(-0.05, 1.05))
        axes[1, column].set(xlabel="x nominal" if curve != "sensor noise" else "x sensor-noise's levels",
                            ylabel="time to target, IQM [s] (3 s: not reached)")
    axes[0, 0].legend(fontsize=7)
    on = f" on {data['env_id']}" if "env_id" in data else ""
    fig.suptitle(f"Robustness{on}: {data['episodes']} episodes per point and seed, from the protocol's starts")
    written: list[Path] = []
    _save(fig, path, written)
    return path


HEADLINE_CONDITIONS = ("c11", "c11-starts", "random-targets", "random-shifts", "sensor-noise", "delay-1")
"""the conditions of the README's headline table (headline_overview)"""
ABLATION_TAGS = frozenset({"interface-ablation"})
"""the registry tags of runs that answer a question about a design choice rather than compete:
their rows are in the comparison's tables, not in the headline"""


def headline_entries(entries: list[dict]) -> list[dict]:
    """The entries the headline table shows: all but the ablations' (ABLATION_TAGS) and the learned
    rows whose runs trained on none of the training distributions (zero-shot in all of them: issue
    58 item 5 keeps zero-shot rows out of the headline; they are in the full tables)."""
    return [e for e in entries if not ABLATION_TAGS & set(e.get("tags") or ()) and not _trained_on_no_draws(e)]


def _trained_on_no_draws(record: dict) -> bool:
    """Whether a learned or offline record's run trained on none of the training distributions'
    draws (the registry's tags for a registered run, else the record's own)."""
    return record["kind"] in ("learned", "offline") and not trained_for(run_tags(record))


ZERO_SHOT = "zero-shot"
"""the mark of a zero-shot cell (agents.experiments.entries.is_zero_shot)"""


def headline_overview(entries: list[dict]) -> str:
    """The headline table (the README's and docs/comparison.md's): the overview of the headline
    entries in HEADLINE_CONDITIONS, a zero-shot cell marked without its numbers."""
    return overview(headline_entries(entries), HEADLINE_CONDITIONS, hide_zero_shot=True)


def overview(entries: list[dict], conditions: tuple[str, ...] | None = None, hide_zero_shot: bool = False) -> str:
    """Every policy across the conditions (default: all of the entries'): time to target (IQM),
    with (success rate / collision rate) where not every episode succeeds without a collision;
    "-" where none succeeds. A zero-shot cell is marked so; with ``hide_zero_shot`` (the headline)
    the mark stands alone, without the numbers."""
    conditions = list(conditions or dict.fromkeys(e["condition"] for e in entries))
    lines = ["#### Overview: time to target, IQM (success rate / collision rate where not 1 / 0)", "",
             "| policy | " + " | ".join(conditions) + " |", "|---|" + "---|" * len(conditions)]
    for name in dict.fromkeys(row_of(e) for e in entries if e["condition"] in conditions):
        cells = []
        for condition in conditions:
            found = [e for e in entries if e["condition"] == condition and row_of(e) == name]
            if not found:
                cells.append("n/a")
                continue
            e = found[0]
            if hide_zero_shot and is_zero_shot(e):
                cells.append(ZERO_SHOT)
                continue
            time_text = "-" if e["success_rate"] == 0 else f"{e['time_iqm']:.3f} s"
            clean = e["success_rate"] == 1.0 and e["collision_rate"] == 0.0
            cell = time_text if clean else f"{time_text} ({rate_text(e['success_rate'])} / {rate_text(e['collision_rate'])})"
            cells.append(f"{cell}, {ZERO_SHOT}" if is_zero_shot(e) else cell)
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def condition_tables(entries: list[dict]) -> str:
    """One table per condition (and every seed of the learned entries): the comparison's format."""
    lines = []
    for name in dict.fromkeys(e["condition"] for e in entries):
        description = CONDITIONS[name].description if name in CONDITIONS else name
        here = [e for e in entries if e["condition"] == name]
        lines += [f"#### {name}: {description}", "", _caption(here), "",
                  "| policy | kind | mode | seeds | episodes | success | collisions | time to target, IQM [95 % CI] (s) "
                  "| energy (J) | P(faster than heuristic) | decision, median / p95 (us) | episodes with a collision |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for e in here:
            seeds = "-" if e["seeds"] is None else ",".join(map(str, e["seeds"]))
            p = e.get("probability_faster_than_heuristic")
            p_text = "-" if p is None else f"{p:.2f} [{e['probability_faster_ci'][0]:.2f}, {e['probability_faster_ci'][1]:.2f}]"
            kind = f"{e['kind']}, {ZERO_SHOT}" if is_zero_shot(e) else e["kind"]
            lines.append(f"| {e['name']} | {kind} | {e['control_mode']} | {seeds} | {e['episodes']} | "
                         f"{rate_text(e['success_rate'])} | {rate_text(e['collision_rate'])} | {e['time_iqm']:.4f} "
                         f"[{e['time_ci'][0]:.4f}, {e['time_ci'][1]:.4f}] | {e['energy_mean']:.1f} | {p_text} | "
                         f"{_decision_cell(e)} | {rate_claim(e['collision_rate'], episodes_of(e))} |")
        for e in (e for e in entries if e["condition"] == name and e.get("solve_time")):
            t = e["solve_time"]
            lines += ["", f"{e['name']}: solve time per control step median {1e3 * t['median']:.1f} ms, 95th percentile "
                          f"{1e3 * t['p95']:.1f} ms, worst {1e3 * t['worst']:.1f} ms ({t['solves']} solves, "
                          f"{t['failures']} not converged)"]
        lines += precision_table([e for e in entries if e["condition"] == name])
        per_seed = [e for e in entries if e["condition"] == name and e.get("per_seed")]
        if per_seed:
            lines += ["", "Every seed (success, collisions, mean time of the successful episodes, energy):", ""]
            for e in per_seed:
                cells = [f"seed {s['seed']}: {rate_text(s['success_rate'])} / {rate_text(s['collision_rate'])} / "
                         + ("-" if s["time_mean"] is None else f"{s['time_mean']:.4f} s") + f" / {s['energy_mean']:.0f} J"
                         for s in e["per_seed"]]
                lines.append(f"- {e['name']}: " + "; ".join(cells))
        lines.append("")
    return "\n".join(lines)


def _caption(entries: list[dict]) -> str:
    """What a condition's table was scored on: the id and the episodes (entries kept before
    entries named their id say so)."""
    ids = sorted({e.get("env_id", "an id not recorded") for e in entries})
    episodes = sorted({e["episodes"] for e in entries})
    learned = any(e["seeds"] for e in entries)
    count = " or ".join(map(str, episodes))
    return (f"Scored on `{'`, `'.join(ids)}`: {count} episode{'s' if episodes != [1] else ''} per policy"
            + (" and per training seed of a learned policy" if learned else "")
            + ", on the condition's evaluation seeds."
            + (f" Decision: the policy's wall time per control step on the machine that ran the comparison, "
               f"timed over the condition's first {DECISION_EPISODES} episodes (one thread; the MPC's: its "
               "solver's time per step, over every episode)" if any("decision_time" in e for e in entries) else ""))


def _decision_cell(e: dict) -> str:
    """A row's compute per decision in microseconds (the MPC's: its solve time, marked so)."""
    t = e.get("decision_time")
    if t is None:
        return "-"
    return f"{1e6 * t['median']:,.0f} / {1e6 * t['p95']:,.0f}" + (" (solve)" if t.get("timed") == "solve" else "")


def _interval_cell(point: float, interval, digits: int = 3) -> str:
    return f"{point:.{digits}f} [{interval[0]:.{digits}f}, {interval[1]:.{digits}f}]"


def precision_table(entries: list[dict]) -> list[str]:
    """The lines of one condition's table at every band (scara_gym.benchmark.episodes.BAND_NAMES):
    success rates, times to each band (IQM, 95 % CI; the time limit where not reached) and the
    normalized time score (IQM, 95 % CI) with the reference that scores 1; none for entries kept
    before the looser bands were scored."""
    entries = [e for e in entries if f"success_rate_{BAND_NAMES[-1]}" in e]
    if not entries:
        return []
    references = sorted({e["time_score_reference"] for e in entries if "time_score_reference" in e})
    if references:
        scored = max(e.get("time_score_episodes", 0) for e in entries)
        reference = (f"normalized time score per episode: 0 = pd + shield's time, 1 = {', '.join(references)}'s "
                     f"time in the same episode (the optimal replay where the condition has it, else the MPC); "
                     f"{scored} of {entries[0]['episodes']} episodes scored (those where the reference reaches the "
                     "target sooner than pd + shield)")
    else:
        reference = ("no normalized time score: neither the optimal replay nor the MPC was evaluated in this "
                     "condition")
    header = ([f"success {band}" for band in BAND_NAMES] + [f"time to {band}, IQM [95 % CI] (s)" for band in BAND_NAMES]
              + ["normalized time score, IQM [95 % CI]"])
    lines = ["", f"At each precision (bands in rad and m; {reference}):", "",
             "| policy | " + " | ".join(header) + " |", "|---|" + "---|" * len(header)]
    for e in entries:
        cells = [rate_text(e["success_rate"])] + [rate_text(e[f"success_rate_{band}"]) for band in BAND_NAMES[1:]]
        cells.append(_interval_cell(e["time_iqm"], e["time_ci"]))
        cells += [_interval_cell(e[f"time_iqm_{band}"], e[f"time_ci_{band}"]) for band in BAND_NAMES[1:]]
        cells.append(_interval_cell(e["time_score_iqm"], e["time_score_ci"], 2) if "time_score_iqm" in e else "-")
        lines.append(f"| {e['name']} | " + " | ".join(cells) + " |")
    return lines


def comparison_figures(entries: list[dict], traces: dict, groups: dict, out: Path) -> list[Path]:
    """The comparison's figures under ``out``: tip paths, time against energy, learning curves."""
    plt = _pyplot()

    written = []
    if "c11" in traces:
        written.append(tip_paths({label: [trace] for label, trace in traces["c11"].items()},
                                 out / "comparison_tip_paths.png", "Tip paths on the C11 target (learned: first seed)",
                                 figsize=(6.5, 6), legend_size=7))

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for e, color in zip([e for e in entries if e["condition"] == "c11"], plt.cm.tab10.colors):
            ax.errorbar(e["time_iqm"], e["energy_mean"], xerr=[[e["time_iqm"] - e["time_ci"][0]],
                                                              [e["time_ci"][1] - e["time_iqm"]]],
                        fmt="o", color=color, label=e["name"])
            for s in e.get("per_seed", []):
                if s["time_mean"] is not None:
                    ax.plot(s["time_mean"], s["energy_mean"], ".", color=color, alpha=0.6)
        ax.set(xlabel="time to target [s] (IQM, 95 % CI; dots: seeds)", ylabel="electrical energy [J]",
               title="Time against energy, C11 target", yscale="log")
        ax.legend(fontsize=7)
        _save(fig, out / "comparison_time_energy.png", written)

    curves = {}
    for (algorithm, mode), run_dirs in sorted(groups.items()):
        data = [np.load(d / "eval" / "evaluations.npz") for d in run_dirs if (d / "eval" / "evaluations.npz").exists()]
        data = [d for d in data if len(d["timesteps"])]
        if data:
            n = min(len(d["timesteps"]) for d in data)
            curves[f"{algorithm} ({mode})"] = (data[0]["timesteps"][:n], np.array([d["results"][:n].mean(axis=1) for d in data]))
    if curves:
        fig, ax = plt.subplots(figsize=(7, 4))
        for (label, (steps, returns)), color in zip(curves.items(), plt.cm.tab10.colors):
            point, interval = interval_estimates(
                {label: returns[:, None, :]},
                lambda s: np.array([iqm(s[:, :, t]) for t in range(s.shape[-1])]), 500, 0)
            ax.plot(steps, point[label], color=color, label=f"{label}, {returns.shape[0]} seeds")
            ax.fill_between(steps, interval[label][0], interval[label][1], color=color, alpha=0.2)
        ax.set(xlabel="environment steps", ylabel="evaluation return (IQM over seeds, 95 % CI)",
               title="Learning curves", xscale="log")
        ax.legend(fontsize=8)
        _save(fig, out / "comparison_learning_curves.png", written)
    return written


def learning_curve_figure(data: dict, path: Path) -> Path:
    """A learning curve (agents.experiments.learning_curves' data): success at each band, collisions
    and the IQM time to target against the environment steps, every seed drawn, the mean thick."""
    plt = _pyplot()
    bands = [key[len("success_"):] for key in data["mean"][0] if key.startswith("success_")] if data["mean"] else []
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for band, color in zip(bands, plt.cm.tab10.colors):
        for rows in data["seeds"].values():
            steps = [r["steps"] for r in rows]
            axes[0].plot(steps, [r[f"success_{band}"] for r in rows], "-", color=color, alpha=0.35, lw=1)
            axes[2].plot(steps, [r[f"time_iqm_{band}"] for r in rows], "-", color=color, alpha=0.35, lw=1)
        axes[0].plot(data["budgets"], [r[f"success_{band}"] for r in data["mean"]], "o-", color=color, lw=2,
                     label=f"band {band} rad")
        axes[2].plot(data["budgets"], [r[f"time_iqm_{band}"] for r in data["mean"]], "o-", color=color, lw=2)
    for rows in data["seeds"].values():
        axes[1].plot([r["steps"] for r in rows], [r["collision_rate"] for r in rows], "-", color="C3", alpha=0.35)
    axes[1].plot(data["budgets"], [r["collision_rate"] for r in data["mean"]], "o-", color="C3", lw=2)
    axes[0].set(ylabel="success rate", ylim=(-0.05, 1.05))
    axes[1].set(ylabel="collision rate", ylim=(-0.05, 1.05))
    axes[2].set(ylabel="time to target, IQM [s] (3 s: not reached)")
    for ax in axes:
        ax.set(xscale="log", xlabel="environment steps")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{data['run']} on {data['env_id']}: {data['scored_on']}; {len(data['seeds'])} seeds (thin), "
                 "their mean (thick)", fontsize=9)
    written: list[Path] = []
    _save(fig, path, written)
    return path
