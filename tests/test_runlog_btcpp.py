"""``btfsm conform --log``: recordings that real BehaviorTree.CPP 4 writes (FileLogger2,
``.btlog``) while it ticks random trees conform to the model; tampered ones do not.

The trees are the peer test's (``test_peer_btcpp.trees``: every control and decorator node,
async and sync actions, conditions, skill requests), ticked ``TICKS`` times in
``behaviortreepy`` with a ``FileLogger`` attached, all in this process. Each log is checked
against the model with free leaves (each action may return any of its outcomes: what a
user checks). The logs to tamper with must conform to the model pinned to the leaves'
tables (``allow``: the run's only behaviour), and each tampered log (one checked
transition's status changed, dropped, swapped with the next checked one, or given another
node's uid) must be rejected by it. A dropped transition is never the last one (a log cut
at a tick's end is the recording of a shorter run); transitions the check does not check
(docs/interop.md section 5: resets of finished nodes to IDLE, the RUNNING a sync action
records before its result) are not tampered with.

Cost: 400 recordings per run (100 random trees, each run with 4 seeded random tables of
leaf answers; checking the recordings is the slow part, about 20 ms each); the first 150
recordings are tampered, four ways each. ``BTFSM_LONG=1``: 1,000 trees (4,000
recordings), every one tampered. (Whether BehaviorTree.CPP ticks these trees as the btcpp
profile does, status by status and callback by callback, is test_peer_btcpp.py's, on
1,000 trees by default.)
"""
from __future__ import annotations

import os
import random
import time

import pytest
from hypothesis import HealthCheck, given, settings

bt = pytest.importorskip("behaviortreepy")

from btcpp_peer import build  # noqa: E402
from test_peer_btcpp import TICKS, trees  # noqa: E402

from btfsm.errors import ModelError  # noqa: E402
from btfsm.interop.btcpp_export import to_btcpp_xml  # noqa: E402
from btfsm.interop.btlog import read_btlog  # noqa: E402
from btfsm.verify.runlog import check_btlog  # noqa: E402

_BT = {"S": bt.NodeStatus.SUCCESS, "F": bt.NodeStatus.FAILURE, "R": bt.NodeStatus.RUNNING}
LONG = bool(os.environ.get("BTFSM_LONG"))
TREES = 1000 if LONG else 100
TABLES = 4  # runs of each tree, with other leaf answers
LOGS = TREES * TABLES
TAMPERED = LOGS if LONG else 150
BATCH = 100
DRAIN = 10.0  # seconds a batch's loggers may take to write everything


def _record(specs, folder, first=0):
    """Tick each spec's tree in real BehaviorTree.CPP with a FileLogger2 attached and check
    each recording against the model (free leaves): [(model, leaves, BtLog, LogVerdict)].

    FileLogger2 (BT.CPP 4.8) writes from its own thread and drops what it has not written
    yet when it is destroyed, so the loggers of a batch stay alive until every file is read
    back complete: a file that is empty, ends inside a transition or does not conform is
    read again (for up to ``DRAIN`` seconds; the last reading is what the test judges)."""
    out, live, paths = [], [], []
    for n, spec in enumerate(specs):
        model, leaves = build(spec, TICKS)
        factory = bt.BehaviorTreeFactory()
        now = [0]
        for name, (kind, table) in leaves.items():
            def answer(node, table=table):
                return _BT[table[now[0]]]
            if kind in ("async", "skill"):
                factory.register_simple_stateful_action(name, answer, answer, lambda node: None)
            elif kind == "sync":
                factory.register_simple_action(name, answer)
            else:
                factory.register_simple_condition(name, answer)
        tree = factory.create_tree_from_text(to_btcpp_xml(model))
        path = os.path.join(folder, f"run{first + n}.btlog")
        logger = bt.FileLogger(tree, path)
        for now[0] in range(TICKS):
            tree.tick_exactly_once()
        live.append([tree, logger])
        out.append([model, leaves, path, None])
        paths.append(path)
    sizes = None
    for _ in range(50):  # first until the files stop growing (the writers wake every 10 ms)
        time.sleep(0.02)
        now_sizes = [os.path.getsize(p) for p in paths]
        if now_sizes == sizes:
            break
        sizes = now_sizes
    pending, deadline = list(range(len(out))), time.monotonic() + DRAIN
    while pending:
        still = []
        for i in pending:
            model, leaves, path = out[i][0], out[i][1], paths[i]
            try:
                log = read_btlog(open(path, "rb").read(), path)
            except ModelError:  # the writer thread is inside a transition
                still.append(i)
                continue
            verdict = check_btlog(model, log)
            out[i][2:] = [log, verdict]
            if log.transitions and verdict.conforms:
                live[i].clear()  # complete: its logger may go
            else:
                still.append(i)
        pending = still if time.monotonic() < deadline else []
        if pending:
            time.sleep(0.05)
    live.clear()
    return out


def _pin(model, leaves):
    """allow(step): the clock ticked and every primitive answered its leaf's table."""
    t_slot = model.program.slots.index(next(s for s in model.program.slots if s.name == "t"))

    def allow(step):
        t = step.state[t_slot]
        if ("env", "clock") not in step.events:
            return False
        for ev in step.events:
            if ev[0] == "outcome":
                parts = ev[1].split("/")  # a skill's FSM state 'L_fsm/work', or 'INSTANCE/.../L' in a SubTree
                leaf = parts[-2][:-len("_fsm")] if parts[-1] == "work" and parts[-2].endswith("_fsm") else parts[-1]
                if ev[2][0].upper() != leaves[leaf][1][t]:
                    return False
        return True
    return allow


_SPECS: list = []


def _retabled(spec, rng, done=None):
    """The same tree with new random leaf answers (one table per leaf name: a SubTree's
    tree used in two places has the same leaves in both)."""
    done = {} if done is None else done
    if spec[0] in ("async", "sync", "cond", "skill"):
        alphabet = "SFR" if spec[0] in ("async", "skill") else "SF"
        if spec[1] not in done:
            done[spec[1]] = "".join(rng.choice(alphabet) for _ in spec[2])
        return (spec[0], spec[1], done[spec[1]])
    body = spec[2]
    body = [_retabled(c, rng, done) for c in body] if isinstance(body, list) else _retabled(body, rng, done)
    return (spec[0], spec[1], body, *spec[3:])


@settings(derandomize=True, max_examples=TREES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(trees())
def _collect(spec):
    rng = random.Random(len(_SPECS))
    _SPECS.append(spec)
    _SPECS.extend(_retabled(spec, rng) for _ in range(TABLES - 1))


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    _collect()
    folder = tmp_path_factory.mktemp("btlogs")
    runs = []
    for k in range(0, len(_SPECS), BATCH):
        runs += _record(_SPECS[k:k + BATCH], str(folder), k)
    return runs


def test_real_btcpp_logs_conform(recorded):
    """Every recording conforms to the model (its leaves free, as a user checks it)."""
    assert len(recorded) == LOGS
    unread = [path for _, _, path, verdict in recorded if verdict is None]
    assert not unread, unread[:3]
    assert all(log.transitions for _, _, log, _ in recorded)
    bad = [verdict.first for _, _, _, verdict in recorded if not verdict.conforms]
    assert not bad, (len(bad), bad[:3])


def _checked(log, leaves):
    """Indices of the transitions the check checks (not resets of finished nodes, not a
    sync action's RUNNING before its result)."""
    sync = {uid for uid, nd in log.nodes.items() if not nd.children and leaves.get(nd.name, ("",))[0] == "sync"}
    last, out = {}, []
    for i, (_, uid, status) in enumerate(log.transitions):
        prev = last.get(uid, 0)
        last[uid] = status
        if (status == 0 and prev in (2, 3)) or (status == 1 and uid in sync):
            continue
        out.append(i)
    return out


def _tampered(log, leaves, rng):
    idx = _checked(log, leaves)
    uids = sorted(log.nodes)
    tr = log.transitions
    for kind in ("status", "drop", "swap", "uid"):
        # the last transition may be a tick of its own: without it the log is a shorter run
        i = rng.choice(idx[:-1] if kind == "drop" and len(idx) > 1 else idx)
        if kind == "drop" and i == len(tr) - 1:
            continue
        new = list(tr)
        usec, uid, status = tr[i]
        if kind == "status":
            new[i] = (usec, uid, rng.choice([s for s in range(4) if s != status]))
        elif kind == "drop":
            del new[i]
        elif kind == "swap":
            pairs = [(a, b) for a, b in zip(idx, idx[1:]) if b == a + 1 and tr[a][1] != tr[b][1]]
            if not pairs:
                continue
            a, b = rng.choice(pairs)
            new[a], new[b] = (tr[a][0], tr[b][1], tr[b][2]), (tr[b][0], tr[a][1], tr[a][2])
        else:
            if len(uids) < 2:
                continue
            new[i] = (usec, rng.choice([u for u in uids if u != uid]), status)
        yield kind, i, type(log)(log.xml, log.root, log.nodes, log.start_usec, new)


def test_tampered_logs_are_rejected(recorded):
    rng = random.Random(20)
    counts, accepted = {}, []
    for model, leaves, log, _ in recorded[:TAMPERED]:
        allow = _pin(model, leaves)
        assert check_btlog(model, log, allow=allow).conforms  # the run itself: its only behaviour
        for kind, i, bad in _tampered(log, leaves, rng):
            counts[kind] = counts.get(kind, 0) + 1
            verdict = check_btlog(model, bad, allow=allow)
            if verdict.conforms:
                accepted.append((kind, i, log.transitions, bad.transitions))
    assert min(counts.values()) > TAMPERED // 2, counts
    assert not accepted, accepted[:2]
