"""The comparison's typed entry: its checks, its one serialization, the fields code reads instead of labels."""

import json

import pytest

from agents.experiments import registry
from agents.experiments.entries import IDENTITY, Entry, is_heuristic, is_zero_shot, row_of, shield_added


def heuristic(**more) -> Entry:
    return Entry("dec-continue, tuned (d=0.0664 m)", "heuristic", None, "pd", "c11-starts", "Scara-C11-v2",
                 variant="continue", setting="tuned", figures={"success_rate": 1.0}, **more)


def test_the_record_holds_the_fields_then_the_figures_and_is_json():
    e = heuristic()
    record = e.record()
    assert list(record)[:len(IDENTITY)] == list(IDENTITY) and record["success_rate"] == 1.0
    assert record["row"] == "dec-continue, tuned" == row_of(record)  # the label's distance is not read
    assert json.loads(json.dumps(record)) == record
    assert is_heuristic(record, "continue", "tuned") and not is_heuristic(record, "continue", "margin")
    more = e.with_figures(decision_time={"median": 1e-5})
    assert more.figures["decision_time"] == {"median": 1e-5} and "decision_time" not in e.figures  # frozen


def test_a_record_kept_before_entries_were_typed_gives_its_row_from_its_label():
    assert row_of({"name": "dec-restart, margin (d=0.0797 m)"}) == "dec-restart, margin"
    assert row_of({"name": "pd + shield"}) == "pd + shield"


def test_shield_added_is_a_learned_run_the_comparison_puts_behind_the_shield():
    learned = Entry("ppo + shield", "learned", "ppo + shield", "pd", "c11", "Scara-C11-v2", (0, 1), shielded=True,
                    shield_range="nominal", run="ppo")
    trained_behind = Entry("x", "learned", "x", "pd", "c11", "Scara-C11-v2", (0,), shielded=True,
                           shield_range="nominal", run="x", tags=("shielded",))
    pd = Entry("pd + shield", "pd", None, "pd", "c11", "Scara-C11-v2", shielded=True, shield_range="nominal")
    assert [shield_added(e.record()) for e in (learned, trained_behind, pd)] == [True, False, False]


@pytest.mark.parametrize("wrong, match", [
    (dict(kind="robot"), "kind must be one of"),
    (dict(setting=None), "a variant and a setting"),
    (dict(setting="best"), "setting must be one of"),
    (dict(shielded=True), "names its shield's range"),
    (dict(figures={"name": "x"}), "must not hold the entry's own fields"),
    (dict(figures={"row": "x"}), "must not hold the entry's own fields"),
])
def test_an_entry_that_contradicts_itself_is_refused(wrong, match):
    fields = {"name": "dec-continue, tuned", "kind": "heuristic", "algorithm": None, "control_mode": "pd",
              "condition": "c11", "env_id": "Scara-C11-v2", "variant": "continue", "setting": "tuned"}
    with pytest.raises(ValueError, match=match):
        Entry(**{**fields, **wrong})


def test_zero_shot_is_a_training_distribution_whose_draws_the_run_never_trained_on():
    assert registry.trained_for({"perturbed-starts", "residual"}) == {"c11-starts"}
    assert not registry.zero_shot({"perturbed-starts"}, "c11-starts")
    assert registry.zero_shot({"perturbed-starts"}, "random-targets") and registry.zero_shot((), "random-shifts")
    assert not registry.zero_shot((), "c11") and not registry.zero_shot((), "sensor-noise")  # not a training draw

    def record(kind, run, condition, tags=()):
        return {"kind": kind, "run": run, "condition": condition, "tags": list(tags)}

    assert is_zero_shot(record("learned", "ppo", "random-targets"))
    assert not is_zero_shot(record("learned", "ppo-random-targets", "random-targets"))
    assert not is_zero_shot(record("pd", None, "random-targets"))  # classical rows are never zero-shot
    # a registered run: the registry's tags, whatever a record published before says (the BC runs
    # learn from the c11 datasets, whose starts are drawn in the start region)
    assert not is_zero_shot(record("offline", "bc-c11-expert", "c11-starts", tags=["offline", "residual"]))
    assert is_zero_shot(record("offline", "bc-c11-expert", "random-targets"))
    # a run the registry does not hold: its record's own tags
    assert not is_zero_shot(record("learned", "my-run", "random-shifts", tags=["domain-randomized"]))
    assert is_zero_shot(record("learned", "my-run", "random-shifts"))
    for name, run in registry.RUNS.items():  # a learning-curve run trains on the draws it is scored on
        if run.trained_on is not None:
            assert run.trained_on in registry.trained_for(run.tags), name
