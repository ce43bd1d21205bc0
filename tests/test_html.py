"""The HTML report (btfsm/html.py), driven in a real browser.

Headless Debian chromium through selenium (chromedriver at /usr/bin/chromedriver; never a
browser download). Skipped, with the reason, when chromium, chromedriver, selenium or
Graphviz is missing. The page must load without console errors, make no network request,
step through the ticks with the slider and the arrow keys, and show at every tick of
every counterexample of ``btfsm check original`` (and of a model-level counterexample
and a trace) the node statuses, halts, FSM states and fired edges the counterexample's
JSON (or the trace) records.
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import pytest

from btfsm.bt import walk
from btfsm.cli import main
from btfsm.models.registry import load_builtin as builtin_model
from btfsm.trace import ReplayOracle, encode_state, read_trace

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--window-size=1400,1000")


def _skip_reason():
    if shutil.which("dot") is None:
        return "Graphviz 'dot' is not installed"
    if CHROMIUM is None or CHROMEDRIVER is None:
        return "no chromium/chromedriver (Debian: apt-get install chromium chromium-driver)"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install -e '.[test]')"
    return None


needs_browser = pytest.mark.skipif(_skip_reason() is not None, reason=_skip_reason() or "")
needs_dot = pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz 'dot' is not installed")


@pytest.fixture(scope="module")
def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in FLAGS:
        opts.add_argument(flag)
    profile = tempfile.mkdtemp(prefix="btfsm-chromium-")
    opts.add_argument(f"--user-data-dir={profile}")
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def _open(driver, path) -> None:
    """Load the page; fail on a console error or on any request but the page itself."""
    driver.get("about:blank")
    driver.get_log("performance")  # drain what the browser did before
    driver.get_log("browser")
    url = Path(path).resolve().as_uri()
    driver.get(url)
    assert driver.execute_script("return document.readyState") == "complete"
    assert driver.execute_script("return typeof window.btfsmView") == "object"
    errors = [e for e in driver.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]
    assert not errors, errors
    requests = []
    for entry in driver.get_log("performance"):
        msg = json.loads(entry["message"])["message"]
        if msg["method"] == "Network.requestWillBeSent":
            requests.append(msg["params"]["request"]["url"])
    assert requests and all(u == url or u.startswith("data:") for u in requests), requests


def _shown(driver) -> dict:
    return driver.execute_script("return window.btfsmView.shown()")


def _key(driver, key) -> None:
    from selenium.webdriver.common.by import By

    driver.find_element(By.TAG_NAME, "body").send_keys(key)


def _expected_nodes(model, ce) -> list:
    """Per tick, the node statuses of a model-level counterexample, re-run from what its
    JSON records by name (events and outcomes, as ``btfsm replay`` of a trace answers)."""
    prog = model.program
    state = encode_state(prog, ce["initial"])
    out = [({}, [])]
    for st in ce["steps"]:
        step = prog.step(state, ReplayOracle(prog, {"env": st["env"], "outcomes": st["outcomes"]}), True)
        nodes, halted = {}, []
        for ev in step.events:
            if ev[0] == "status":
                nodes[ev[1]] = ("RUNNING", "SUCCESS", "FAILURE")[ev[2]]
            elif ev[0] == "halt":
                nodes[ev[1]] = "halted"
                halted.append(ev[1])
        out.append((nodes, sorted(halted)))
        state = step.state
    return out


def _walk_counterexample(driver, model, ce, run: int) -> None:
    """Step through run ``run`` with the right arrow key and compare every tick."""
    from selenium.webdriver.common.keys import Keys

    driver.execute_script("window.btfsmView.selectRun(arguments[0])", run)
    expected = _expected_nodes(model, ce) if ce["level"] == "model" else None
    in_fsms = {n.name for path, root in model.roots() if path != "tree" for n in walk(root)}  # FSM states' subtrees
    fsms = [f.name for f in model.fsms] if ce["level"] == "model" else [ce["fsm"]]
    initial = {f: ce["initial"].get(f"{f}.state") for f in fsms}
    for k in range(len(ce["steps"]) + 1):
        shown = _shown(driver)
        assert (shown["run"], shown["tick"], shown["slider"]) == (run, k, k)
        if k == 0:
            assert {f: shown["fsm"][f] for f in fsms} == initial
            assert shown["fired"] == [] and shown["nodes"] == {}
        else:
            st = ce["steps"][k - 1]
            assert {f: shown["fsm"][f] for f in fsms} == {f: st["fsm"][f][0] for f in fsms}, k
            assert sorted(map(tuple, shown["fired"])) == sorted(map(tuple, st["fired"])), k
            assert shown["halted"] == sorted(set(st["halted"])), k
            for kind, site, _outcome, status in (c for c in st["choices"] if c[0] == "outcome"):
                if site in shown["nodes"] and site not in st["halted"]:  # an Action of the tree
                    assert shown["nodes"][site] == status, (k, site)
            if expected is not None:
                assert (shown["nodes"], shown["halted"]) == expected[k], k
            else:  # one request to one FSM: only its states' subtrees can run
                assert set(shown["nodes"]) <= in_fsms, k
        _key(driver, Keys.ARROW_RIGHT)
    assert _shown(driver)["tick"] == len(ce["steps"])  # the last tick stays


@needs_browser
def test_check_original_page_steps_through_every_counterexample(browser, tmp_path, capsys):
    from selenium.webdriver.common.keys import Keys

    page, ces = tmp_path / "r.html", tmp_path / "ce"
    assert main(["check", "original", "--html", str(page), "--counterexample-dir", str(ces), "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    _open(browser, page)
    data = browser.execute_script("return window.btfsmView.data")
    model = builtin_model("original")
    files = sorted(ces.iterdir())
    assert len(files) == 3
    by_property = {r["property"]: i for i, r in enumerate(data["runs"])}
    for path in files:
        ce = json.loads(path.read_text())
        _walk_counterexample(browser, model, ce, by_property[ce["property"]])
    # the dead branch's run (a lint): every node's status, tick by tick
    (lints,) = [p for p in report["properties"] if p["name"] == "lints"]
    dead = [w["run"] for w in lints["info"]["warnings"] if w.get("run")]
    assert dead and len(data["runs"]) == 3 + len(dead)
    for k, ce in enumerate(dead):
        _walk_counterexample(browser, model, ce, 3 + k)
    # the whole FSM instead of the states the counterexamples visit: the same highlights
    run = by_property["goal-reachability"]
    browser.execute_script("window.btfsmView.selectRun(arguments[0]); window.btfsmView.setTick(1)", run)
    before = _shown(browser)
    toggle = browser.find_element("css selector", "section.fsm button.toggle")
    toggle.click()
    assert browser.execute_script("return document.querySelector('section.fsm .view[data-view=full]').hidden") is False
    assert _shown(browser) == before and before["fsm"]["movement_manager"] is not None
    toggle.click()
    # the slider and the keys Home/End, left arrow
    browser.execute_script("window.btfsmView.selectRun(arguments[0])", by_property["goal-reachability"])
    browser.execute_script("var s = document.getElementById('slider'); s.value = '2';"
                           "s.dispatchEvent(new Event('input'))")
    assert _shown(browser)["tick"] == 2 and browser.find_element("id", "slider").get_attribute("value") == "2"
    _key(browser, Keys.ARROW_LEFT)
    assert _shown(browser)["tick"] == 1
    _key(browser, Keys.END)
    assert _shown(browser)["tick"] == 2
    _key(browser, Keys.HOME)
    assert _shown(browser)["tick"] == 0
    # the lasso's cycle start is on the timeline
    run = by_property["no-dead-states"]
    browser.execute_script("window.btfsmView.selectRun(arguments[0])", run)
    loop = data["runs"][run]["loop"]
    assert loop is not None
    cells = browser.execute_script("return Array.from(document.querySelectorAll('#strip > div')).map(d => d.className)")
    assert "loop" in cells[loop + 1].split() and all("loop" not in c.split() for i, c in enumerate(cells) if i != loop + 1)


@needs_browser
def test_model_level_counterexample_lights_up_the_tree(browser, tmp_path):
    page, ces = tmp_path / "r.html", tmp_path / "ce"
    assert main(["check", "original-preemptive", "--property", "workable-reachability", "--html", str(page),
                 "--counterexample-dir", str(ces)]) == 1
    _open(browser, page)
    (path,) = ces.iterdir()
    ce = json.loads(path.read_text())
    _walk_counterexample(browser, builtin_model("original-preemptive"), ce, 0)
    lit = browser.execute_script("return document.querySelectorAll('.tree g.node.st-RUNNING').length")
    assert lit > 0


@needs_browser
def test_replayed_trace_opens_in_the_same_viewer(browser, tmp_path):
    from selenium.webdriver.common.keys import Keys

    trace, page = tmp_path / "t.jsonl", tmp_path / "t.html"
    assert main(["run", "ariac-preemptive", "--ticks", "25", "--seed", "3", "--trace", str(trace)]) == 0
    assert main(["replay", str(trace), "ariac-preemptive", "--html", str(page)]) == 0
    _, records = read_trace(trace)
    _open(browser, page)
    for rec in records:
        _key(browser, Keys.ARROW_RIGHT)
        shown = _shown(browser)
        assert shown["tick"] == rec["tick"] + 1
        assert shown["fsm"] == {f: v[0] for f, v in rec["fsm"].items()}
        edges = [tuple(x) for x in rec["fired"] if not x[1].startswith("<")]  # <withdraw> etc. are notes
        assert sorted(map(tuple, shown["fired"])) == sorted(edges)
        for node, status in rec["changes"].items():  # a node whose status changed ran (or was halted) then
            assert shown["nodes"].get(node) == status or node in shown["halted"], (rec["tick"], node)


@needs_dot
def test_a_thousand_tick_replay_stays_under_5_mb(tmp_path):
    trace, page = tmp_path / "t.jsonl", tmp_path / "t.html"
    assert main(["run", "ariac-preemptive", "--ticks", "1000", "--seed", "1", "--trace", str(trace)]) == 0
    assert main(["replay", str(trace), "ariac-preemptive", "--html", str(page)]) == 0
    size = os.path.getsize(page)
    assert size < 5_000_000, size
    text = page.read_text(encoding="utf-8")
    assert "<script src" not in text and "<link" not in text and "http://" not in text.replace(
        "http://www.w3.org/", "")


def test_without_graphviz_the_html_flag_says_why(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PATH", str(tmp_path))  # no dot there
    page = tmp_path / "r.html"
    assert main(["check", "original", "--property", "determinism", "--html", str(page)]) == 2
    err = capsys.readouterr().err
    assert "Graphviz" in err and "'dot'" in err and "Traceback" not in err
    assert not page.exists()


def test_a_trace_that_differs_is_marked_at_its_first_differing_step(tmp_path):
    from btfsm.html import trace_run

    trace = tmp_path / "t.jsonl"
    assert main(["run", "ariac-preemptive", "--ticks", "30", "--seed", "2", "--trace", str(trace)]) == 0
    header, records = read_trace(trace)
    k = next(i for i, r in enumerate(records) if i >= 5 and r["outcomes"])
    records[k]["status"] = "FAILURE" if records[k]["status"] != "FAILURE" else "SUCCESS"
    run = trace_run(builtin_model("ariac-preemptive"), header, records, "t")
    assert [m[0] for m in run["marks"]] == [k + 1] and "differs" in run["marks"][0][1]
    assert len(run["ticks"]) == len(records) + 1
    assert run["ticks"][k + 1]["nodes"] == records[k]["changes"]  # from there: the trace's own records


@needs_browser
def test_conform_page_shows_the_first_mismatch_and_the_cell(browser, tmp_path):
    """A scene whose check cannot hold (no slack): the first scenario does not conform;
    its run is in the page with the cell's pictures and the mismatch marked."""
    from btfsm.files import load_data
    from btfsm.html import write_page
    from btfsm.sim.cell_view import ConformViews
    from btfsm.sim.conformance import conform
    from btfsm.sim.scene import builtin_scene, scene_from_data

    data = load_data(builtin_scene("two_area"))  # btfsm's YAML reading: `on:` stays a string
    data["checks"][1]["slack"] = [0, 0]
    model = builtin_model("two-area")
    views = ConformViews(model, max_pictures=3)
    rows = []

    def result(i, sc, res):
        views.result(i, sc, res)
        rows.append({"scenario": i, "seed": sc.seed, "ticks": res.ticks, "conforms": res.mismatch is None,
                     "mismatch": None if res.mismatch is None else str(res.mismatch)})

    out = conform(model, 1, 0, 300.0, scene=scene_from_data(data), path=False, on_result=result, views=views)
    assert not out.conforms
    page = tmp_path / "c.html"
    write_page(page, model, **views.page(rows))
    _open(browser, page)
    run = browser.execute_script("return window.btfsmView.data.runs[0]")
    # the initial state and every tick before the one that showed the mismatch (0-based)
    assert run["kind"] == "cell" and len(run["ticks"]) == out.results[0].mismatch.tick + 1
    assert [m[0] for m in run["marks"]] == [len(run["ticks"]) - 1] and "mismatch" in run["marks"][0][1]
    assert 2 <= len(run["pictures"]) <= 3
    browser.execute_script("window.btfsmView.setTick(1)")
    src = browser.execute_script("var i = document.querySelector('#picture img'); return i && i.src")
    assert src and src.startswith("data:image/png;base64,")


def test_a_recorded_btlog_opens_in_the_same_viewer(browser, tmp_path, capsys):
    """``conform --log RUN --html``: the model's run that explains a log real BT.CPP wrote
    (docs/examples/btcpp_record.py) is a run of the page, whose leaves finish in the order
    and with the statuses the log records; a log that does not conform is marked where the
    explanation stops."""
    import subprocess
    import sys

    pytest.importorskip("behaviortreepy")
    from selenium.webdriver.common.keys import Keys

    from btfsm.html import read_page
    from btfsm.interop.btlog import read_btlog

    root = Path(__file__).resolve().parent.parent
    record, tree = root / "docs" / "examples" / "btcpp_record.py", root / "models" / "examples" / "pick_place_btcpp.xml"
    good, bad = tmp_path / "run.btlog", tmp_path / "stuck.btlog"
    subprocess.run([sys.executable, str(record), str(good)], check=True, capture_output=True)
    subprocess.run([sys.executable, str(record), str(bad), "--stuck-sensor"], check=True, capture_output=True)
    page = tmp_path / "log.html"
    assert main(["conform", "--log", str(good), str(tree), "--html", str(page)]) == 0
    capsys.readouterr()
    log = read_btlog(good.read_bytes(), str(good))
    leaves = {uid for uid, nd in log.nodes.items() if not nd.children}
    names = {"SUCCESS": 2, "FAILURE": 3}
    recorded = [(log.nodes[uid].name, status) for _, uid, status in log.transitions
                if uid in leaves and status in (2, 3)]
    run = read_page(page)["runs"][0]
    assert run["kind"] == "log" and not run["marks"]
    leaf_names = {n.rsplit("/", 1)[-1] for n in (x for t in run["ticks"] for x in t["nodes"])}
    shown = [(n.rsplit("/", 1)[-1], names[s]) for t in run["ticks"] for n, s in t["nodes"].items()
             if s in names and n.rsplit("/", 1)[-1] in {log.nodes[u].name for u in leaves}]
    # every leaf result the page shows is one BT.CPP recorded, and every leaf is shown (a
    # leaf that finishes twice in one tick, retried, shows its last result there: 3 here)
    from collections import Counter

    assert leaf_names and not Counter(shown) - Counter(recorded)
    assert {n for n, _ in shown} == {n for n, _ in recorded} and len(shown) >= len(recorded) - 5
    _open(browser, page)
    for k in range(1, len(run["ticks"])):
        _key(browser, Keys.ARROW_RIGHT)
        assert _shown(browser)["tick"] == k
    assert main(["conform", "--log", str(bad), str(tree), "--html", str(page)]) == 1
    run = read_page(page)["runs"][0]
    assert [m[0] for m in run["marks"]] == [len(run["ticks"]) - 1] and "no run explains" in run["marks"][0][1]
    _open(browser, page)
