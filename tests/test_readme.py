"""The README's example model builds, checks clean, and runs."""
import os
import re

from btfsm.oracles import RandomOracle
from btfsm.runtime import Runtime

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _example():
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    ns: dict = {}
    exec(re.search(r"```python\n(.*?)```", text, re.S).group(1), ns)  # our own README
    return ns["model"]


def test_readme_example_checks_clean():
    from btfsm.verify import check

    report = check(_example())
    assert report.exit_code == 0, report.format_text()


def test_readme_example_runs():
    rt = Runtime(_example(), fallback=RandomOracle(3))
    for k in range(50):
        rt.tick(["arrive"] if k == 2 else [])
    assert rt.vars["part"] is True
