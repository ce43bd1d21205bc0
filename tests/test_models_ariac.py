"""The corrected ARIAC model (models/ariac.py): template, FSM design rules, the two
executives, random runs in the runtime, and the full btfsm check."""
import importlib
import pytest
from hypothesis import given, settings
from memo_strategies import st

from btfsm.oracles import RandomOracle
from btfsm.runtime import Runtime
from btfsm.status import Status
from btfsm.models.ariac import AREAS, HUBS, ROTATIONS, SKILLS, arm_fsm, baseline, generate_fsm, preemptive

VARIANTS = {"preemptive": preemptive, "baseline": baseline}


@pytest.fixture(scope="module")
def fsm():
    return arm_fsm()


def test_template_instances(fsm):
    assert len(fsm.states) == 42 and len({s.id for s in fsm.states}) == 42
    assert fsm.goals == tuple(f"{k}_{a}" for a in AREAS for k in ("pick", "place"))
    assert fsm.initial == "approach_bins"
    for x, y, z in ROTATIONS:
        states, edges, markers = generate_fsm(x, y, z)
        assert len(states) == 14
        # the two transits arriving at x belong to x's instance
        assert {s.id for s in states} >= {f"{y}_to_{x}", f"{z}_to_{x}", f"approach_{x}"}
    owned = [s.id for x, y, z in ROTATIONS for s in generate_fsm(x, y, z)[0]]
    assert sorted(owned) == sorted(s.id for s in fsm.states)  # the union partitions the states


def test_every_goal_applies_in_every_state(fsm):
    """No withdraw goal: every goal has its own way out of every state."""
    for s in fsm.states:
        for g in fsm.goals:
            assert fsm.edges_from(s.id, g), (s.id, g)


def test_no_unguarded_double_edges(fsm):
    for s in fsm.states:
        for g in fsm.goals:
            by_trigger = {}
            for e in fsm.edges_from(s.id, g):
                by_trigger.setdefault("direct" if e.direct else e.on, []).append(e)
            for trig, es in by_trigger.items():
                if len(es) > 1:
                    assert all(e.guard is not None for e in es), (s.id, g, trig)


def test_markers_not_shadowed_and_failures_reported(fsm):
    assert arm_fsm().validate({"move": {Status.RUNNING, Status.SUCCESS}, "gripper": {Status.SUCCESS},
                               "grasp": {Status.RUNNING, Status.SUCCESS, Status.FAILURE},
                               "record_pose": {Status.SUCCESS}, "detach": {Status.SUCCESS}}) == []
    for x in AREAS:
        fail = [m for m in fsm.markers if m.state == f"grasp_{x}" and m.outcome == Status.FAILURE]
        assert len(fail) == 1 and fail[0].goals == (f"pick_{x}",)


@pytest.mark.parametrize("variant", VARIANTS)
def test_builds_without_warnings_or_lints(variant):
    m = VARIANTS[variant]()
    assert m.warnings == () and m.program.lints == []
    assert m.var("tray").hi == 18 and m.var("queue").hi == 2


def test_parameters_are_checked():
    with pytest.raises(ValueError):
        preemptive(n_tray=0)
    with pytest.raises(ValueError):
        generate_fsm("bins", "conveyor", "agv", grasp_attempts=0)


# ------------------------------------------------------------------ runtime runs
def _arrivals(rng_seed, p):
    import random

    rng = random.Random(rng_seed)
    return lambda rt: ["arrive"] if rt.vars["queue"] < rt.model.var("queue").hi and rng.random() < p else []


def _run(model, seed, ticks, p=0.05):
    rt = Runtime(model, fallback=RandomOracle(seed))
    events = _arrivals(seed + 1000, p)
    prog = model.program
    goals, violations = [], []
    for _ in range(ticks):
        step = rt.tick(events(rt))
        violations += step.violations
        for name, inv in prog.invariants:
            assert inv(list(rt.state)), (name, rt.vars, rt.fsm_state("arm"))
        goals.append(rt.fsm_state("arm")[1])
        if rt.vars["tray"] == model.var("tray").hi and rt.fsm_state("arm")[1] is None:
            break
    return rt, goals, violations


@pytest.mark.parametrize("variant", VARIANTS)
def test_random_runs_complete_the_kit(variant):
    m = VARIANTS[variant](n_tray=3)
    for seed in range(12):
        rt, goals, violations = _run(m, seed, 3000)
        assert violations == [], (seed, violations)
        assert rt.vars["tray"] == 3, seed


def _preempted(goals):
    """Goal switches from a kitting skill straight to a belt skill (no idle tick between)."""
    return [(a, b) for a, b in zip(goals, goals[1:])
            if a in ("pick_bins", "place_agv") and b in ("pick_conveyor", "place_bins")]


def test_preemptive_switches_to_the_belt_at_once_baseline_never():
    pre, base = [], []
    for seed in range(10):
        pre += _preempted(_run(preemptive(n_tray=4), seed, 3000, p=0.1)[1])
        base += _preempted(_run(baseline(n_tray=4), seed, 3000, p=0.1)[1])
    assert pre and not base


def _count_run(seed, p, n=4, ticks=600):
    """Run with recorded events; return (releases on the tray, places halted after their release)."""
    m = preemptive(n_tray=n)
    rt = Runtime(m, fallback=RandomOracle(seed), record=True)
    events = _arrivals(seed, p)
    released = halted_after = 0
    for _ in range(ticks):
        rt.tick(events(rt))
        evs = rt.last.events
        released += sum(1 for ev in evs if ev[0] == "fire" and ev[2] == "release_agv->detach_place_agv")
        halted_after += any(ev[:2] == ("halt", "register_placing") for ev in evs) and not rt.vars["gripper_full"]
        # the model's count equals the releases (the last one may still be in its escape)
        assert rt.vars["tray"] == released or (rt.fsm_state("arm")[0] in ("detach_place_agv", "escape_agv")
                                               and rt.vars["tray"] == released - 1)
    return released, halted_after


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000), p=st.sampled_from([0.02, 0.05, 0.1]))
def test_tray_counts_the_parts_released_on_it(seed, p):
    """The model's tray count equals the releases at the AGV, even when a place is
    preempted after its release (the Effects decorator counts it on halt)."""
    _count_run(seed, p)


def test_places_are_preempted_after_their_release():
    runs = [_count_run(seed, 0.05) for seed in range(6)]
    assert sum(r for r, _ in runs) > 10 and sum(h for _, h in runs) > 0


# ------------------------------------------------------------------ btfsm check
def _check(model):
    verify = importlib.import_module("btfsm.verify")
    return verify.check(model)


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_check_property_holds(variant):
    report = _check(VARIANTS[variant]())
    results = getattr(report, "properties", None) or report.results
    failed = {r.name: r.counterexample for r in results if r.holds is not True and r.name != "lints"}
    assert failed == {}
    assert report.complete


@pytest.mark.parametrize("kw", [dict(n_tray=2, queue_max=1, grasp_attempts=1), dict(n_tray=5, queue_max=3, grasp_attempts=3)])
def test_other_sizes_pass_too(kw):
    for make in VARIANTS.values():
        report = _check(make(**kw))
        assert all(r.holds for r in report.results if r.name != "lints"), kw


def test_lints_are_only_the_unused_chains():
    """The symmetric template has chains the tree never uses (pick from the AGV, place on
    the belt) and preemption edges that one tree or the other never takes."""
    report = _check(preemptive())
    lints = next(r for r in report.results if r.name == "lints").notes
    unreached = {str(n).split(":")[0].rsplit(".", 1)[1] for n in lints if "state '" in str(n)}
    assert unreached == {f"{s}_agv" for s in ("enable_gripper", "grasp", "record_pose", "detach_pick", "raise",
                                               "put_back", "disable_gripper")} | {
        f"{s}_conveyor" for s in ("put_back", "put", "release", "detach_place", "escape")}


def test_skills_derivation_ariac():
    from btfsm.verify.skills import check_support, counts, derive

    names = {goal: s for s, (goal, _) in SKILLS.items()}
    for variant, make in VARIANTS.items():
        d = derive(make())
        c = counts(d)
        pairs = {(names[d.skills[a].goal], names[d.skills[b].goal], k) for a, b, k in d.pairs if a is not None}
        assert c["completion"] == 7
        assert {(a, b) for a, b, k in pairs if k == "completion"} == {
            ("S1", "S2"), ("S1", "S4"), ("S2", "S1"), ("S2", "S3"), ("S3", "S2"), ("S3", "S4"), ("S4", "S3")}
        pre = {(a, b) for a, b, k in pairs if k == "preemption"}
        if variant == "baseline":
            assert pre == set()
        else:
            assert pre == {("S1", "S3"), ("S1", "S4"), ("S2", "S3"), ("S2", "S4")}
            # the paper's reading: 9 of 16 = 7 after completion + 2 that only a preemption gives
            assert (c["completion_or_preemption"], c["only_by_preemption"]) == (9, 2)
        assert all(s.supported for s in check_support(d))
        assert all(s.supported for s in check_support(d, where="held"))  # the stricter reading too
    assert set(HUBS) == {"approach_agv", "approach_bins", "approach_conveyor"}
