"""The hash-partitioned BFS on Dask (btfsm.verify.distributed, issue 13 point 5) gives the
exact state and transition counts of the one-process search, on a local two-worker
cluster (worker threads in this process: quick, no spawned interpreters). Skipped when
dask[distributed] is not installed (the ``dist`` extra; the ``test`` extra includes it).
"""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("distributed")

from dask.distributed import Client, LocalCluster  # noqa: E402

from btfsm.models.pickplace import pickplace  # noqa: E402
from btfsm.verify.distributed import explore_distributed, owner  # noqa: E402
from btfsm.verify.explore import explore  # noqa: E402


@pytest.fixture(scope="module")
def client():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as c:
        yield c


@pytest.mark.parametrize("args,kwargs", [((4,), {}), ((3,), {"dead": True}), ((2,), {"bug": True})])
def test_counts_equal_one_process(client, args, kwargs):
    ts = explore(pickplace(*args, **kwargs))
    r = explore_distributed(client, pickplace, args, kwargs)
    assert (r.states, r.transitions) == (ts.n_states, ts.n_transitions)
    assert sum(r.per_partition) == r.states and min(r.per_partition) > 0  # both workers own states


def test_level_synchronous_rounds(client):
    ts = explore(pickplace(3))
    r = explore_distributed(client, pickplace, (3,), message_min=0)  # one BFS level per round
    assert (r.states, r.transitions) == (ts.n_states, ts.n_transitions)
    assert r.levels == int(ts.depth().max()) + 2  # the levels, then one round that finds nothing


def test_owner_spreads_codes():
    own = owner(np.arange(100_000) * 7, 2)
    assert set(own.tolist()) == {0, 1} and abs(int(own.sum()) - 50_000) < 1_000
