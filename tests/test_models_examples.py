"""Teaching models: two-area, the preemption spectrum, and the seeded-defect catalogue."""
import importlib
import pytest

from btfsm.oracles import SucceedOracle
from btfsm.oracles import RandomOracle
from btfsm.runtime import Runtime
from btfsm.status import Status
from btfsm.models.examples import defects, spectrum
from btfsm.models.examples.two_area import two_area
from btfsm.models.registry import BUILTIN, DEFECTS, load_builtin, names



def _verify():
    return importlib.import_module("btfsm.verify")


def _violated(model):
    report = _verify().check(model)
    return {r.name for r in report.results if r.holds is False}, report


# ------------------------------------------------------------------ registry
def test_registry_builds_every_model_with_its_name():
    for name in names():
        m = load_builtin(name)
        assert m.name == name, (name, m.name)
        assert BUILTIN[name].startswith("btfsm.models.")


def test_registry_unknown_name_lists_the_names():
    from btfsm.errors import ModelError

    with pytest.raises(ModelError) as exc:
        load_builtin("no-such-model")
    assert "ariac-preemptive" in str(exc.value)


def test_file_loader_resolves_builtin_names():
    files = importlib.import_module("btfsm.files")
    assert files.load_model("spectrum-hold").name == "spectrum-hold"


# every built-in model round-trips through YAML and JSON: tests/test_files.py,
# test_builtin_models_round_trip (one case per model; this file ran the YAML half again)


# ------------------------------------------------------------------ two-area
def test_two_area_moves_every_part():
    m = two_area()
    for seed in range(10):
        rt = Runtime(m, fallback=RandomOracle(seed))
        for _ in range(500):
            rt.tick(["arrive"] if m.program.env[0][1](list(rt.state)) else [])
            if rt.vars["placed"] == 3:
                break
        assert rt.vars["placed"] == 3 and not rt.vars["holding"], seed


def test_two_area_passes_the_check():
    bad, report = _violated(two_area())
    assert bad == set() and report.complete


# ------------------------------------------------------------------ spectrum
MODELS = {"continue": spectrum.continue_, "hold": spectrum.hold, "reverse": spectrum.reverse}


@pytest.mark.parametrize("mode", MODELS)
def test_spectrum_models_pass_the_check(mode):
    bad, _ = _violated(MODELS[mode]())
    assert bad == set()


def test_spectrum_reaction_orders_the_three_points():
    cont, hold, rev = (spectrum.reaction(MODELS[k]()) for k in ("continue", "hold", "reverse"))
    # continue waits for the rest of the job; reverse undoes what was done; hold just parks
    assert [cont[w] for w in spectrum.WORK] == sorted((cont[w] for w in spectrum.WORK), reverse=True)
    assert [rev[w] for w in spectrum.WORK] == sorted(rev[w] for w in spectrum.WORK)
    assert len(set(hold.values())) == 1
    assert cont["w1"] > hold["w1"] and rev["w3"] > hold["w3"]


def _fsm_run(model, state, goal, ticks):
    prog = model.program
    tokens = []
    for _ in range(ticks):
        state = prog.fsm_step(state, "arm", goal, (), SucceedOracle()).state
        tokens.append(prog.fsm_state(state, "arm")[0])
    return tokens, state


def _at(model, token, **world):
    prog = model.program
    s = list(prog.initial)
    ids = [st.id for st in model.fsm("arm").states]
    s[next(i for i, sl in enumerate(prog.slots) if sl.name == "arm.state")] = ids.index(token)
    for k, v in world.items():
        s[prog.scope[k].index] = v
    return tuple(s)


def test_hold_resumes_where_it_stopped():
    m = spectrum.hold()
    # w2 ran, then the call: park, serve, and the job goes on at w3
    _, state = _fsm_run(m, _at(m, "w1"), "work", 1)
    assert m.program.decode(state)["stage"] == 1
    tokens, state = _fsm_run(m, state, "serve", 5)
    assert tokens == ["home", "go", "act", "back", "home"] and m.program.decode(state)["stage"] == 1
    tokens, _ = _fsm_run(m, state, "work", 3)
    assert tokens == ["w2", "w3", "home"]


def test_reverse_undoes_and_continue_finishes():
    m = spectrum.reverse()
    tokens, _ = _fsm_run(m, _at(m, "w3"), "serve", 4)
    assert tokens == ["u2", "u1", "home", "go"]
    m = spectrum.continue_()
    tokens, _ = _fsm_run(m, _at(m, "w2"), "serve", 3)
    assert tokens == ["w3", "home", "go"]


def test_spectrum_skills_are_a_preemption_each():
    from btfsm.verify.skills import check_support, derive

    for mode, make in MODELS.items():
        d = derive(make())
        kinds = {(d.skills[a].goal, d.skills[b].goal, k) for a, b, k in d.pairs if a is not None}
        assert ("work", "serve", "preemption") in kinds, mode
        assert all(s.supported for s in check_support(d)), mode


# ------------------------------------------------------------------ the catalogue
@pytest.mark.parametrize("name", sorted(defects.EXPECTED))
def test_catalogue_verdicts(name):
    """Each seeded defect violates exactly the properties in the table."""
    bad, report = _violated(load_builtin(name))
    assert bad == defects.EXPECTED[name]
    assert DEFECTS[name] in bad or DEFECTS[name] == "lints"
    for r in report.results:
        if r.holds is False:
            assert r.counterexample is not None, (name, r.name)


def test_catalogue_covers_every_property():
    assert set(DEFECTS.values()) >= set(defects.PROPERTIES) | {"lints"}
    assert set(DEFECTS) == set(defects.EXPECTED) and set(DEFECTS) <= set(BUILTIN)


def test_shadowed_marker_is_a_build_warning_and_a_lint():
    m = defects.shadowed_marker()
    assert [el for el, text in m.warnings] == ["fsms.arm.markers.put:direct"]
    _, report = _violated(m)
    lints = next(r for r in report.results if r.name == "lints").notes
    assert any("put:direct" in str(n) and "shadowed" in str(n) for n in lints)


def test_catalogue_counterexamples_point_at_the_defect():
    v = _verify()
    r = v.check(defects.invariant(), ["invariants"]).results[0]
    assert r.counterexample.steps[-1]["fsm"]["arm"][0] == "alarm"
    r = v.check(defects.contract(), ["contracts"]).results[0]
    assert any(name == "arm/reach" for st in r.counterexample.steps for name, _ in st["outcomes"])
    r = v.check(defects.nondeterminism(), ["determinism"]).results[0]
    assert "weigh" in r.counterexample.format_text()
    r = v.check(defects.trap(), ["workable-reachability"]).results[0]
    assert r.counterexample.steps[-1]["state"]["stop"] is True
