"""``btfsm conform --log`` on py_trees runs recorded by ``btfsm.interop.pytrees.RunRecorder``.

Random trees of the py_trees peer test (``test_peer_pytrees.peer_trees``) run in real
py_trees 2.6 (``to_pytrees``, leaves answering their tables) with the recorder attached;
every recording conforms to the model, and every tampered one (a visited node's status
changed, a visited node dropped, two swapped, a node added to or removed from the
RUNNING ones) is rejected by the model pinned to the tables.
"""
from __future__ import annotations

import io
import random

import pytest
from hypothesis import HealthCheck, given, settings

py_trees = pytest.importorskip("py_trees")

from pytrees_peer import STATUS, build_model  # noqa: E402
from test_peer_pytrees import TICKS, peer_trees  # noqa: E402

from btfsm import Guard, walk  # noqa: E402
from btfsm.interop.pytrees import RUN_FORMAT, RunRecorder, to_pytrees  # noqa: E402
from btfsm.verify.runlog import PYTREES_FORMAT, check_pytrees_run, read_pytrees_run  # noqa: E402

TREES = 300


def _record(tree, table):
    model = build_model(tree)
    clock = [0]
    root = to_pytrees(model, answer=lambda name: STATUS[table[name][clock[0]]])
    bt = py_trees.trees.BehaviourTree(root)
    out = io.StringIO()
    recorder = RunRecorder(out)
    bt.visitors.append(recorder)
    for clock[0] in range(TICKS):
        bt.tick()
    recorder.close()
    return model, out.getvalue()


def _pin(tree, table):
    guards = [n.name for n in walk(tree) if isinstance(n, Guard)]

    def allow(tick, step):
        for g in guards:
            if ("env", f"{g}_{'off' if table[g][tick] == 'F' else 'on'}") not in step.events:
                return False
        return all(ev[2][0].upper() == table[ev[1]][tick] for ev in step.events if ev[0] == "outcome")
    return allow


def _tampered(run, rng):
    ticks = run.ticks
    k = rng.randrange(len(ticks))
    visited, running = ticks[k]
    for kind in ("status", "drop", "swap", "running"):
        new = list(visited)
        runs = set(running)
        if kind == "status":
            i = rng.randrange(len(new))
            new[i] = (new[i][0], rng.choice([s for s in ("RUNNING", "SUCCESS", "FAILURE") if s != new[i][1]]))
        elif kind == "drop":
            del new[rng.randrange(len(new))]
        elif kind == "swap":
            pairs = [i for i in range(len(new) - 1) if new[i][0] != new[i + 1][0]]
            if not pairs:
                continue
            i = rng.choice(pairs)
            new[i], new[i + 1] = new[i + 1], new[i]
        else:
            runs ^= {rng.randrange(len(run.nodes))}
        yield kind, type(run)(run.nodes, ticks[:k] + [(new, frozenset(runs))] + ticks[k + 1:])


def test_formats_agree():
    assert RUN_FORMAT == PYTREES_FORMAT


@settings(max_examples=TREES, derandomize=True, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(peer_trees())
def test_recorded_py_trees_runs_conform_and_tampered_ones_do_not(case):
    tree, table = case
    model, text = _record(tree, table)
    run = read_pytrees_run(text, "run.jsonl")
    assert len(run.ticks) == TICKS
    verdict = check_pytrees_run(model, run)
    assert verdict.conforms, verdict.first
    allow = _pin(tree, table)
    assert check_pytrees_run(model, run, allow=allow).conforms
    rng = random.Random(str(tree))
    for kind, bad in _tampered(run, rng):
        verdict = check_pytrees_run(model, bad, allow=allow)
        assert not verdict.conforms, (kind, text, bad.ticks)
        assert verdict.first["text"]
