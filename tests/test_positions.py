"""The position abstraction of the timed ARIAC models (btfsm.positions, btfsm.sim.durations;
docs/verification.md 2.1): the split FSM has the original's behaviour, and the derived
durations come from the scene's own motions.
"""
from __future__ import annotations

import dataclasses
import math

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from btfsm import FSM, Edge, Model, ModelError, Primitive, State, running, success
from btfsm.models import ariac
from btfsm.positions import base_state, entries_of, split_by_entry, split_by_goal, split_by_guard
from btfsm.verify.explore import explore


#: the arrivals' spacing the untimed comparisons keep (s): 2 ticks, and the copies by a belt
#: part's age split at 1 tick (``_aged_at_ticks``), so every copy is entered
SPACING = 0.2


def _aged_at_ticks() -> dict:
    """The stored derivation with its copies by age (``since(arrive) >= 60``...) split at
    1, 2... ticks instead: the same copies and entries, the same structure, a small counter."""
    t = ariac.derived_timing()
    for copies in t["ages"].values():
        tags = sorted(copies, key=lambda tag: float(tag[len("age"):]))
        for k, tag in enumerate(tags):
            lo, hi = (f"since(arrive) >= {k}" if k else ""), (f"since(arrive) < {k + 1}" if k + 1 < len(tags) else "")
            copies[tag] = " and ".join(x for x in (lo, hi) if x) or "true"
    return t


def _untimed(model):
    f = model.fsms[0]
    return dataclasses.replace(model, fsms=(dataclasses.replace(f, states=tuple(
        dataclasses.replace(s, duration=None) for s in f.states)),), responses=(),
        environment=tuple(dataclasses.replace(e, min_interval=SPACING) for e in model.environment))


def _spaced(model):
    """``model`` with the arrivals spaced as ``_untimed`` spaces them."""
    return dataclasses.replace(model, environment=tuple(dataclasses.replace(e, min_interval=SPACING)
                                                        for e in model.environment))


def _projected(ts, drop=()) -> tuple:
    """(states, transitions) of ``ts`` with every FSM copy named by the state it was split from
    (and the variables ``drop`` left out)."""
    def one(i):
        return tuple(sorted((k, base_state(v) if k.endswith(".state") else v) for k, v in ts.decode(i).items()
                            if k not in drop))
    def label(lab):  # an outcome's site is "fsm/state"
        return tuple(tuple(f"{x.split('/')[0]}/{base_state(x.split('/', 1)[1])}" if isinstance(x, str) and "/" in x
                           else x for x in item) for item in lab)
    states = [one(i) for i in range(ts.n_states)]
    return set(states), {(states[int(s)], states[int(d)], label(ts.labels[int(lab)]))
                         for s, d, lab in zip(ts.src, ts.dst, ts.label)}


@pytest.mark.parametrize("variant", ["preemptive", "baseline"])
def test_the_split_fsm_behaves_as_the_original(variant):
    """Without its durations, the split model's reachable states and transitions, each copy
    named by its state, are exactly the original model's (1 tray part keeps it small; the
    arrivals unscoped, as in the original: ``arrivals="any"``; both spaced by ``SPACING``,
    which the copies by age read)."""
    m = getattr(ariac, variant)(n_tray=1)
    split = _untimed(ariac.timed(m, arrivals="any", timing=_aged_at_ticks()))
    assert len(split.fsms[0].states) > len(m.fsms[0].states)
    assert any("%age" in s.id for s in split.fsms[0].states)
    assert _projected(explore(split)) == _projected(explore(_spaced(m)))


def test_the_fsm_split_by_the_bins_behaves_as_the_original():
    """With the bins' occupancy (``timed(m, bins="tracked")``: the pick and place copies at
    the bins split by guards on it, ``split_by_guard``), the split model's states and
    transitions without the bins' variables are the original's, and with them (BTFSM_LONG=1)
    those of the unsplit model with the variables (``ariac.with_bins``); 1 tray part,
    arrivals unscoped."""
    import os

    m = ariac.preemptive(n_tray=1)
    split = _untimed(ariac.timed(m, arrivals="any", bins="tracked", timing=_aged_at_ticks()))
    assert any("%bin3" in s.id for s in split.fsms[0].states)
    ts = explore(split)
    # the bins' variables only observe (no guard reads them): without them, the original's runs
    assert _projected(ts, drop=ariac.BIN_VARIABLES) == _projected(explore(_spaced(m)))
    if os.environ.get("BTFSM_LONG") == "1":  # and with them, the unsplit model's with the variables
        tracked = explore(ariac.with_bins(split_by_goal(_spaced(m), "arm", ariac.derived_timing()["classes"])))
        assert _projected(ts) == _projected(tracked)


def test_expressions_name_every_copy():
    m = ariac.timed(ariac.preemptive(n_tray=2))
    hubs = [s.id for s in m.fsms[0].states if base_state(s.id) == "approach_agv"]
    text = str(m.workable)
    assert len(hubs) > 1 and all(f"'{h}'" in text for h in hubs)


def test_split_errors_name_the_state():
    f = FSM("arm", states=[State("a", "move"), State("b", "move")], initial="a", goals=("g",),
            edges=[Edge("a", "b", "g"), Edge("b", "a", "g")])
    m = Model("m", primitives=[Primitive("move", (running(), success()))], fsms=[f])
    with pytest.raises(ModelError, match="no duration for the entry from b"):
        split_by_entry(m, "arm", {"a": {"": (0, 1)}})
    with pytest.raises(ModelError, match="positions.zz"):
        split_by_goal(m, "arm", {"zz": {"c": ("g",)}})
    assert entries_of(f) == {"a": {"": (False, ()), "b": (False, ("g",))}, "b": {"a": (False, ("g",))}}


def test_the_rest_to_rest_time_is_the_worlds():
    """``Derivation.rest_time`` is the time the scene's arm takes (``World.move_to`` at the
    binding's speed scale), to the world step, for moves in x-y, in z and both."""
    from btfsm.sim.durations import Derivation, _kitting

    scene, binding = _kitting(ariac.preemptive(n_tray=2))
    geo = Derivation(scene, binding)
    from btfsm.sim.scene import World

    for (x, y, z) in [(0.3, -1.0, 1.1), (0.3, -2.9, 0.77), (0.9, -0.5, 1.3), (0.6, -0.8, 0.8)]:
        w = World(scene, 0)
        r = w.robots[binding.robot]
        x0, y0, z0 = r.x, r.y, r.z
        s = binding.speed
        w.move_to(binding.robot, (x, y), s, z=z, acceleration=s * s)
        n = 0
        while not r.arrived:
            w.step()
            n += 1
        want = geo.rest_time(math.hypot(x - x0, y - y0), abs(z - z0))
        assert want <= n * w.dt < want + w.dt + 1e-9


def test_the_stored_table_is_the_derivation(tmp_path):
    """models/ariac_timing.json (and ariac_timing_no_loss.json) is what ``derive`` gives for the moves that need no belt
    tracking (the pursuit samples make the whole derivation take a minute: BTFSM_LONG=1)."""
    import os

    from btfsm.sim import durations

    stored = ariac.derived_timing()
    if os.environ.get("BTFSM_LONG") != "1":
        pytest.skip("the derivation runs a minute of pursuits (BTFSM_LONG=1)")
    got = durations.derive_ariac().to_data()
    assert (got["classes"], got["guards"], got["table"]) == (stored["classes"], stored["guards"], stored["table"])
    got = durations.derive_ariac(no_loss=True).to_data()  # models/ariac_timing_no_loss.json
    assert got == ariac.derived_timing("no_loss")


def _first_late_oracle(ts, rb, bound: int):
    """The worst first late response by an explicit product: (state, ticks the pending
    trigger has waited or None), counted along the transitions (not read from the
    event's interval counter), cut where a pending trigger waited longer than ``bound``."""
    trig = set(int(t) for t in rb.trigger_edges)
    seen, todo, worst = {(0, None)}, [(0, None)], None
    while todo:
        u, age = todo.pop()
        for t in range(int(ts.offsets[u]), int(ts.offsets[u + 1])):
            d = int(ts.dst[t])
            a = 0 if t in trig else (None if age is None else age + 1)
            if t in trig:
                w = int(rb.worst_at[d])
                worst = w if worst is None else max(worst, w)
            if rb.stop[d]:
                a = None
            if a is not None and a > bound:
                continue
            if (d, a) not in seen:
                seen.add((d, a))
                todo.append((d, a))
    return worst


@pytest.mark.parametrize("work,bound", [((0.0, 0.3), 2), ((0.1, 0.4), 3), ((0.0, 0.6), 4), ((0.1, 0.75), 5)])
def test_first_late_is_the_product_search(work, bound):
    """``ResponseBound.first_late`` against an explicit product search on a small model:
    parts arrive at least 0.8 s apart into a queue of two, a worker takes ``work`` seconds
    per part (0.75 s: the queue may never empty, both figures unbounded); the response is
    an empty queue."""
    from btfsm import Action, Condition, EnvEvent, Int, ReactiveSequence
    from btfsm.timing import Response
    from btfsm.verify.properties.response import ResponseBound

    m = Model("q", variables=[Int("q", 0, 2)],
              primitives=[Primitive("work", (running(), success(q="q - 1")), duration=work)],
              tree=ReactiveSequence("root", [Condition("has", "q > 0"), Action("w", primitive="work")]),
              environment=[EnvEvent("arrive", "q < 2", {"q": "q + 1"}, min_interval=0.8)],
              tick_rate=10.0)
    ts = explore(m)
    rb = ResponseBound(ts, Response("r", "event:arrive", "q == 0"))
    worst, path, k = rb.first_late(bound)
    assert worst == _first_late_oracle(ts, rb, bound) <= rb.worst
    assert rb.first_late(8) is None  # the interval (8 ticks) must exceed the bound


def test_a_user_scene_gets_derived_durations_and_a_response_verdict(capsys):
    """``python -m btfsm.sim.durations --scene FILE --trigger T --response R --within S``:
    every primitive the bind table drives gets its slowest run from the scene (context-free;
    tests/test_scene_durations.py), and the requirement a verdict. Bad input: one line, exit 2."""
    from btfsm.sim.durations import main as durations_main

    from pathlib import Path

    scene = str(Path(__file__).resolve().parents[1] / "models" / "scenes" / "two_area.yaml")
    assert durations_main(["--scene", scene, "--trigger", "event:arrive", "--response", "arm.state == 'grasp_in'",
                           "--within", "20"]) == 1
    out = capsys.readouterr().out
    assert "arm.at_in                    [0, 1.733] s" in out and "arm.grasp_in                 [0, 0.211] s" in out
    # unbounded still: the model lets a 4th part arrive while the 3rd is not counted yet (it is,
    # once the retreat ends), and that part is never picked ("or placed == 3" bounds it: 16.4 s)
    assert "worst case unbounded" in out and "response: violated" in out
    assert durations_main(["--scene", scene, "--trigger", "event:arrive", "--response", "arm.goal == 'x'"]) == 2
    err = capsys.readouterr().err
    assert "responses.requirement.response: 'x' is not one of" in err and "Traceback" not in err


def test_a_users_expression_names_a_split_states_copies(tmp_path, capsys):
    """``btfsm bound``/``check --trigger/--response`` and replay read ``F.state == 'X'`` as
    "the token is on a copy of X" when X was split (``X@u``, ``X#c``): an expression
    written against the unsplit model keeps its meaning. A name that is neither a state nor
    split is still an error."""
    from btfsm import SkillRequest
    from btfsm.cli import main
    from btfsm.expr import parse
    from btfsm.files.writing import dump_model
    from btfsm.positions import widen_to_copies

    f = FSM("arm", states=[State("a", "move"), State("b", "move")], initial="a", goals=("g",),
            edges=[Edge("a", "b", "g"), Edge("b", "a", "g")])
    m = Model("m", primitives=[Primitive("move", (running(), success()), duration=(0.1, 0.3))], fsms=[f],
              tree=SkillRequest("go", fsm="arm", goal="g"), tick_rate=10.0)
    s = split_by_entry(m, "arm", {"a": {"": (0, 0.2), "b": (0, 0.5)}})
    assert str(widen_to_copies(parse("arm.state != 'a'"), s)) == str(parse("not (arm.state == 'a@start' or "
                                                                           "arm.state == 'a@b')"))
    path = tmp_path / "split.yaml"
    dump_model(s, str(path))
    out = tmp_path / "worst.json"
    assert main(["bound", str(path), "--trigger", "arm.state == 'b'", "--response", "arm.state == 'a'",
                 "-o", str(out)]) == 0
    assert "worst case: 4 ticks = 0.4 s" in capsys.readouterr().out  # b's run, up to 0.3 s: a@b on its 4th tick
    assert main(["replay", str(out), str(path)]) == 0  # shows the expression as written, not its copies
    assert "confirmed: 'arm.state == 'a'' (2 split copies) first holds 4 tick(s)" in capsys.readouterr().out
    assert main(["bound", str(path), "--trigger", "arm.state == 'b'", "--response", "arm.state == 'c'"]) == 2
    assert "'c' is not one of" in capsys.readouterr().err


def _split_file(tmp_path, response="arm.state == 'a'"):
    """A timed model file with arm state 'a' split by entry (a@start, a@b) and a
    requirement, written against the unsplit model, that names 'a'."""
    from btfsm import SkillRequest
    from btfsm.files.writing import dumps_model

    f = FSM("arm", states=[State("a", "move"), State("b", "move")], initial="a", goals=("g",),
            edges=[Edge("a", "b", "g"), Edge("b", "a", "g")])
    m = Model("m", primitives=[Primitive("move", (running(), success()), duration=(0.1, 0.3))], fsms=[f],
              tree=SkillRequest("go", fsm="arm", goal="g"), tick_rate=10.0)
    text = dumps_model(split_by_entry(m, "arm", {"a": {"": (0, 0.2), "b": (0, 0.5)}}))
    assert "id: a@b" in text and "id: a\n" not in text
    path = tmp_path / "split.yaml"
    path.write_text(text + f"responses:\n  back: {{trigger: \"arm.state == 'b'\", response: \"{response}\", "
                           "within: 0.3}\n")
    return path


def test_a_model_files_response_names_a_split_states_copies(tmp_path, capsys):
    """A requirement in a model file's ``responses:`` naming a split state names its copies,
    as ``--trigger/--response`` does: both routes give the same figures and counterexample,
    which shows the requirement as written; replay confirms it, printing the expression as
    written and how many copies it stands for."""
    import json

    from btfsm.cli import main
    from btfsm.files import load_model

    path = _split_file(tmp_path)
    req = load_model(str(path)).responses[0]
    assert req.response_text == "arm.state == 'a'" and "a@b" in str(req.response)
    found = {}
    for name, args in (("file", []), ("cli", ["--trigger", "arm.state == 'b'", "--response", "arm.state == 'a'",
                                              "--within", "0.3"])):
        ce_dir = tmp_path / name
        assert main(["check", str(path), "--property", "response", "--json", "--counterexample-dir", str(ce_dir)]
                    + args) == 1
        doc = json.loads(capsys.readouterr().out)["properties"][0]
        entry = doc["info"]["responses"]["back" if name == "file" else "cli"]
        assert entry["response"] == "arm.state == 'a'" and entry["worst_ticks"] == 4
        ce_file, = ce_dir.iterdir()
        assert json.loads(ce_file.read_text())["violation"]["response"] == "arm.state == 'a'"
        found[name] = {k: v for k, v in entry.items()}
        assert main(["replay", str(ce_file), str(path)]) == 0
        out = capsys.readouterr().out
        assert "confirmed: 'arm.state == 'a'' (2 split copies) still does not hold" in out, out
        assert "a@start" not in out
    assert found["file"] == found["cli"]


def test_a_requirement_naming_no_state_is_still_an_error(tmp_path, capsys):
    from btfsm.cli import main

    path = _split_file(tmp_path, "arm.state == 'c'")
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "responses.back.response: 'c' is not one of a@start, a@b, b" in err and "Traceback" not in err


_EFFECTS = ({}, {"n": "n + 1 if n < 3 else 0"}, {"n": "0"}, {"n": "3 - n"})


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_a_guard_split_has_the_original_runs(data):
    """``split_by_guard`` against explicit exploration (the brute-force oracle): on random
    three-state FSMs whose edges change a variable n (an environment event bumps it too),
    a state split by a random partition of n's values has exactly the original's states and
    transitions once each copy is named by its state, and the token enters a copy only
    where the copy's guard holds (read after the entering edge's effects)."""
    from btfsm import EnvEvent, Int, SkillRequest

    names = ("a", "b", "c")
    edges = []
    for src in names:
        if data.draw(st.booleans(), label=f"{src} guarded"):
            k = data.draw(st.integers(1, 3))
            pairs = ((f"n < {k}", data.draw(st.sampled_from(names))), (f"n >= {k}", data.draw(st.sampled_from(names))))
        else:
            pairs = ((None, data.draw(st.sampled_from(names))),)
        for guard, dst in pairs:
            edges.append(Edge(src, dst, "g", guard=guard, effects=data.draw(st.sampled_from(_EFFECTS))))
    f = FSM("arm", states=[State(x, "move") for x in names], initial="a", goals=("g",), edges=edges)
    m = Model("m", variables=[Int("n", 0, 3)], primitives=[Primitive("move", (running(), success()))], fsms=[f],
              tree=SkillRequest("go", fsm="arm", goal="g"), environment=[EnvEvent("bump", "n < 3", {"n": "n + 1"})])
    target = data.draw(st.sampled_from(("b", "c")))
    cut = data.draw(st.integers(0, 3))
    split = split_by_guard(m, "arm", {target: {"lo": f"n < {cut}", "hi": f"n >= {cut}"}})
    assert [s.id for s in split.fsms[0].states if base_state(s.id) == target] == [f"{target}%lo", f"{target}%hi"]
    ts = explore(split)
    assert _projected(ts) == _projected(explore(m))
    for s, d in zip(ts.src, ts.dst):
        a, b = ts.decode(int(s)), ts.decode(int(d))
        if b["arm.state"] != a["arm.state"] and "%" in b["arm.state"]:
            assert (b["n"] < cut) == b["arm.state"].endswith("%lo"), (a, b)


def test_a_guard_split_refuses_the_initial_state_and_unknown_states():
    f = FSM("arm", states=[State("a", "move"), State("b", "move")], initial="a", goals=("g",),
            edges=[Edge("a", "b", "g"), Edge("b", "a", "g")])
    m = Model("m", primitives=[Primitive("move", (running(), success()))], fsms=[f])
    with pytest.raises(ModelError, match="the initial state cannot be split"):
        split_by_guard(m, "arm", {"a": {"x": "true"}})
    with pytest.raises(ModelError, match="positions.zz"):
        split_by_guard(m, "arm", {"zz": {"x": "true"}})


def test_the_tray_rows_cover_every_count():
    """``ariac.TRAY_ROWS``: a place on the tray goes to slot ``tray`` (the first free one:
    the slots fill in order). For every kit size n, the copies a model keeps (``least`` at
    most n) have guards of which exactly one holds for each count 0..n, and it names that
    slot (``split_by_guard`` needs them disjoint and together true); the 2-part models keep
    row 0 alone."""
    for n in range(1, 19):
        kept = {c: spec for c, spec in ariac.TRAY_ROWS.items() if spec["least"] <= n}
        for count in range(n + 1):
            hold = [c for c, spec in kept.items() if eval(spec["guard"], {}, {"tray": count})]  # noqa: S307
            assert len(hold) == 1, (n, count, hold)
            assert count >= 18 or count in kept[hold[0]]["slots"], (n, count)
    m = ariac.timed(ariac.preemptive(n_tray=2))
    assert {h for h in (s.id.split("@")[0] for s in m.fsms[0].states) if "#place_agv" in h} == \
        {f"{s}#place_agv%row0" for s in ("approach_agv", "bins_to_agv", "conveyor_to_agv")}


def test_a_timing_holds_only_for_the_goals_it_was_derived_for():
    """``derive`` lets a copy run only for goals some skill request asks for
    (``positions.requested_goals``; the ARIAC trees ask for four of the six), and records
    them: a model that asks for another goal is refused, not timed unsoundly."""
    from btfsm.positions import requested_goals

    t = ariac.derived_timing()
    assert t["requested"] == sorted(requested_goals(ariac.baseline(n_tray=2), "arm")) == \
        ["pick_bins", "pick_conveyor", "place_agv", "place_bins"]
    with pytest.raises(ValueError, match="requests place_bins of FSM 'arm'"):
        ariac.timed(ariac.preemptive(n_tray=2), timing={**t, "requested": ["pick_bins", "pick_conveyor", "place_agv"]})
