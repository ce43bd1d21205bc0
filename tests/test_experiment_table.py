"""The experiment table says over how many trials each column is summed (format_table)."""
from btfsm.sim.experiment import format_table

ROW = {"trials": 1, "completed": 1, "skills": 72, "preemptions": 17, "conveyor_arrivals": 17,
       "conveyor_picks": 17, "lost": 0, "reaction_min": 4.8, "reaction_median": 8.6, "reaction_max": 11.1,
       "reaction_max_fraction": 0.69}


def test_one_trial_against_the_papers_forty_is_said():
    lines = format_table({"preemptive": ROW, "baseline": ROW}).splitlines()
    assert lines[1].split() == ["totals", "over", "1", "trial", "40", "trials", "1", "trial", "40", "trials"]
    assert lines[-1] == ("note: ours are totals over 1 trial per variant, the paper's over 40: "
                         "compare counts per trial, not the totals")


def test_forty_trials_need_no_note():
    table = format_table({"preemptive": dict(ROW, trials=40), "baseline": dict(ROW, trials=40)})
    assert "note:" not in table
    assert table.splitlines()[1].split().count("40") == 4


def test_mixed_counts_are_all_named():
    table = format_table({"preemptive": dict(ROW, trials=3), "baseline": dict(ROW, trials=1)})
    assert "ours are totals over 1 trial or 3 trials per variant" in table
