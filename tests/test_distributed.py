"""The partitioned search and checks (btfsm.verify.distributed; issue 13 point 5, issue 24
point 2) give the exact state and transition counts and the verdicts of the one-process
search, whatever the number of partitions: on a local two-worker Dask cluster (worker
threads in this process: quick, no spawned interpreters), through a scheduler address
as a user's cluster is reached, and with 1 to 8 partitions simulated in this process.
Skipped when dask[distributed] is not installed (the ``dist`` extra; the ``test`` extra
includes it).
"""
from __future__ import annotations

import os

import numpy as np
import pytest

pytest.importorskip("distributed")

from dask.distributed import Client, LocalCluster  # noqa: E402

from btfsm.models import ariac  # noqa: E402
from btfsm.models.pickplace import pickplace  # noqa: E402
from btfsm.verify import distributed as dist  # noqa: E402
from btfsm.verify.explore import explore  # noqa: E402
from btfsm.verify.properties import dead, workable  # noqa: E402
from btfsm.verify.traced import BatchSuccessors  # noqa: E402


@pytest.fixture(scope="module")
def local():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        yield cluster


@pytest.fixture(scope="module")
def client(local):
    with Client(local) as c:
        yield c


def _one(model) -> dict:
    ts = explore(model)
    return {"states": ts.n_states, "transitions": ts.n_transitions, "traps": int(workable.traps(ts).size),
            "dead": int(dead.dead_states(ts).size),
            "sinks": sorted(f.name for f in model.fsms if dead.reachable_sinks(ts, f) is not None)}


def _mine(r) -> dict:
    return {"states": r.counts.states, "transitions": r.counts.transitions, "traps": r.traps, "dead": r.dead,
            "sinks": sorted(k for k, v in r.sinks.items() if v)}


@pytest.mark.parametrize("args,kwargs", [((4,), {}), ((2,), {"bug": True})])
def test_counts_equal_one_process(client, args, kwargs):
    ts = explore(pickplace(*args, **kwargs))
    r = dist.explore_distributed(client, pickplace, args, kwargs)
    assert (r.states, r.transitions) == (ts.n_states, ts.n_transitions)
    assert sum(r.per_partition) == r.states and len(r.per_partition) == 2
    if args == (4,):
        assert min(r.per_partition) > r.states // 4  # the key spreads the states


def test_checks_give_the_one_process_verdicts(client):
    """A model with traps and dead states, and the paper's ARIAC model (both hold)."""
    for factory, args, kwargs in [(pickplace, (3,), {"dead": True}), (ariac.preemptive, (), {})]:  # 8,624 and 1,605 states
        want = _one(factory(*args, **kwargs))
        r = dist.check_distributed(client, factory, args, kwargs)
        assert _mine(r) == want
        assert r.verdicts == {"workable-reachability": want["traps"] == 0,
                              "no-dead-states": want["dead"] == 0 and not want["sinks"]}
    assert want["traps"] == 0 and r.verdicts["workable-reachability"]


def test_a_failing_partition_ends_the_search(client, monkeypatch):
    """A partition's error reaches the caller (the workers run in this process here, so
    the patch reaches them); the search does not wait for buckets that never come."""
    def boom(self, out):
        raise RuntimeError("boom")

    monkeypatch.setattr(dist.Partition, "_explore", boom)
    with pytest.raises(RuntimeError, match="boom"):
        dist.explore_distributed(client, pickplace, (2,), {"bug": True})


def test_a_running_scheduler_by_address(local):
    """``cluster(address)`` is how a user's own cluster is reached (``--scheduler``)."""
    with dist.cluster(local.scheduler_address) as c:
        r = dist.explore_distributed(c, pickplace, (2,), {"bug": True})
    ts = explore(pickplace(2, bug=True))
    assert (r.states, r.transitions) == (ts.n_states, ts.n_transitions)


def test_any_number_of_partitions():
    """The same counts and verdicts with 1, 3 and 8 partitions (simulated in this process),
    rounds ending early (``message_min`` of 50 states) or not, and without rounds."""
    model = pickplace(2, dead=True)
    want = _one(model)
    assert want["traps"] and want["dead"]
    for parts, message_min, rounds in ((1, dist.MESSAGE_MIN, True), (3, 50, True), (8, dist.MESSAGE_MIN, True),
                                       (3, 50, False), (8, dist.MESSAGE_MIN, False)):
        r = dist.simulate(model, parts, keep=True, message_min=message_min, rounds=rounds)
        assert _mine(r) == want
        assert len(r.counts.per_partition) == parts and sum(r.counts.per_partition) == want["states"]
        if not rounds:  # the search as on Dask, on a clock of CPU seconds: the busiest partition's
            assert r.counts.cpu_path <= r.counts.makespan <= r.counts.cpu_seconds + 1e-9


def test_partition_key_takes_the_slots_transitions_change_least():
    model = pickplace(3)
    ts = explore(model)
    st = ts.states
    changed = (st[ts.src] != st[ts.dst]).mean(axis=0)
    key = dist.partition_key(model, 2)
    mults = BatchSuccessors(model).mults
    slots = [mults.index(m) for m, _ in key]
    assert len(slots) >= 2
    varying = [k for k in range(len(mults)) if changed[k] > 0]
    assert sorted(changed[slots]) == sorted(changed[varying])[:len(slots)]
    # a transition inside one key value stays in its partition: few are sent
    r = dist.simulate(model, 2)
    assert r.states_sent < r.states // 5


def test_owner_spreads_codes():
    own = dist.owner(np.arange(100_000) * 7, 2)
    assert set(own.tolist()) == {0, 1} and abs(int(own.sum()) - 50_000) < 1_000
    key = ((1, 10), (100, 10))  # the two lowest decimal digits... of which the second is code // 100
    codes = np.arange(10_000)
    own = dist.owner(codes, 4, key)
    same = (codes % 10 == 3) & ((codes // 100) % 10 == 5)
    assert len(set(own[same].tolist())) == 1  # one key value, one owner
    assert np.bincount(own, minlength=4).min() > 1_000


def test_cli_check_on_a_scheduler(local, capsys):
    """``btfsm check --scheduler ADDRESS``: the partitioned verdicts and counts of the
    one-process check (exit 1: both violated on pickplace3-dead); other properties and
    budgets are refused (exit 2)."""
    import json

    from btfsm import cli

    assert cli.main(["check", "pickplace3-dead", "--scheduler", local.scheduler_address, "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    want = _one(pickplace(3, dead=True))
    assert out["results"] == {"workable-reachability": False, "no-dead-states": False}
    assert (out["states"], out["transitions"], out["traps"], out["dead_states"]) == (
        want["states"], want["transitions"], want["traps"], want["dead"])
    assert cli.main(["check", "defect-trap", "--scheduler", local.scheduler_address,
                     "--property", "workable-reachability"]) == 1
    assert "VIOLATED: 2 reachable state(s)" in capsys.readouterr().out
    assert cli.main(["check", "pickplace3", "--scheduler", local.scheduler_address, "--property", "determinism"]) == 2
    assert "only workable-reachability and no-dead-states run partitioned" in capsys.readouterr().err
    assert cli.main(["check", "pickplace3", "--scheduler", "local:2", "--max-states", "10"]) == 2
    assert cli.main(["check", "pickplace3", "--scheduler", "nowhere"]) == 2


@pytest.mark.skipif(not os.environ.get("BTFSM_LONG"), reason="long run: BTFSM_LONG=1")
def test_every_builtin_model_partitioned():
    """The counts, trap, dead and sink states of every built-in model but the heavy and
    the timed ones, with 3 simulated partitions, equal the one-process ones."""
    from btfsm.files import load_model
    from btfsm.models.registry import BUILTIN, HEAVY
    from btfsm.verify.properties import not_applicable

    for name in BUILTIN:
        if name in HEAVY or "timed" in name:
            continue
        model = load_model(name)
        want = _one(model)
        got = _mine(dist.simulate(model, 3, keep=True))
        if not_applicable(model, "workable-reachability"):
            want["traps"] = got["traps"] = None
        if model.tree is None:
            want["sinks"] = got["sinks"] = None  # judged in the FSMs' open systems
        assert got == want, name


def _eager_rounds(ps, phase):
    """Rounds in which each partition's buckets reach their owners at once, before the
    owners' own step of that round: the order a loaded Dask worker can give (an actor's
    round starts when its thread gets to it)."""
    while True:
        res = []
        for p in ps:
            buckets, stats = p.step(phase)
            for j, b in enumerate(buckets):
                if len(b):
                    ps[j].receive(b)
            res.append(stats)
        if all(sum(s["sent"]) == 0 and s["pending"] == 0 for s in res):
            return res


def test_deliveries_before_a_partitions_round_are_kept():
    """Reversed transitions that reach a partition before its first reverse round are not
    lost (they were: the check then counted reachable states as traps under load)."""
    model = pickplace(2, dead=True)
    want = _one(model)
    succ = BatchSuccessors(model)
    key = dist.partition_key(model, 3, succ=succ)
    ps = [dist.Partition(model, j, 3, True, dist.MESSAGE_MIN, key, succ, dist.ROUND_STATES) for j in range(3)]
    _eager_rounds(ps, "explore")
    for p in ps:
        p.local_checks()
    _eager_rounds(ps, "reverse")
    res = _eager_rounds(ps, "back")
    assert sum(s["traps"] for s in res) == want["traps"]
