"""The HTML report (btfsm/html.py): page sizes and load times in headless chromium.

    python3 benchmarks/html_report.py [--loads 3] [--json]

Writes, in a temporary folder, the pages of ``btfsm check ariac-preemptive --html`` (every
property), ``btfsm check original --html`` (three counterexamples) and a 1,000-tick replay
of ``ariac-preemptive`` (``btfsm run --ticks 1000 --trace``, then ``btfsm replay --html``),
then opens each ``--loads`` times in headless Debian chromium (selenium, /usr/bin/chromium
and /usr/bin/chromedriver; never a browser download) and prints the time to the page's
``load`` event (``performance.getEntriesByType('navigation')``) beside the targets of
issue 22: open in under 2 s, a 1,000-tick replay under 5 MB.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import tempfile
from pathlib import Path

LOAD_TARGET = 2.0  # seconds
SIZE_TARGET = 5_000_000  # bytes, a 1,000-tick replay


def _pages(folder: Path) -> list:
    from btfsm.cli import main

    out = []
    with contextlib.redirect_stdout(io.StringIO()):
        p = folder / "ariac_preemptive.html"
        main(["check", "ariac-preemptive", "--html", str(p)])
        out.append(("check ariac-preemptive (every property)", p))
        p = folder / "original.html"
        main(["check", "original", "--html", str(p)])
        out.append(("check original (3 counterexamples)", p))
        trace, p = folder / "t.jsonl", folder / "replay.html"
        main(["run", "ariac-preemptive", "--ticks", "1000", "--seed", "1", "--trace", str(trace)])
        main(["replay", str(trace), "ariac-preemptive", "--html", str(p)])
        out.append(("replay of 1,000 ticks of ariac-preemptive", p))
    return out


def _driver(profile: str):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--window-size=1400,1000", f"--user-data-dir={profile}"):
        opts.add_argument(flag)
    return webdriver.Chrome(service=Service(shutil.which("chromedriver") or "/usr/bin/chromedriver"), options=opts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loads", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="btfsm-html-") as tmp:
        pages = _pages(Path(tmp))
        driver = _driver(os.path.join(tmp, "profile"))
        try:
            for name, path in pages:
                times = []
                for _ in range(args.loads):
                    driver.get("about:blank")
                    driver.get(path.resolve().as_uri())
                    times.append(driver.execute_script(
                        "return performance.getEntriesByType('navigation')[0].loadEventEnd") / 1000.0)
                rows.append({"page": name, "bytes": path.stat().st_size, "load_s": times})
        finally:
            driver.quit()
    load = os.getloadavg()[0]
    if args.json:
        print(json.dumps({"rows": rows, "load_average": load}))
        return
    print(f"{'page':45} {'size':>10}  load event (s), {args.loads} loads   best/target")
    for r in rows:
        best = min(r["load_s"])
        print(f"{r['page']:45} {r['bytes']:>10,}  {', '.join(f'{t:.2f}' for t in r['load_s']):24} "
              f"{best / LOAD_TARGET:.2f}x of {LOAD_TARGET:g} s")
    replay = rows[-1]["bytes"]
    print(f"1,000-tick replay: {replay:,} bytes = {replay / SIZE_TARGET:.3f}x of the {SIZE_TARGET:,}-byte target")
    print(f"(load average {load:.2f})")


if __name__ == "__main__":
    main()
