"""A PNG of a btfsm HTML report at one tick, in headless Debian chromium (selenium).

    python scripts/html_screenshot.py REPORT.html OUT.png [--run R] [--tick T] [--size 1500,1700]

Made docs/img/html_report.png (the README's picture of the viewer). Uses /usr/bin/chromium
and /usr/bin/chromedriver (apt-get install chromium chromium-driver); never downloads a
browser.
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path


def main() -> None:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("report")
    ap.add_argument("png")
    ap.add_argument("--run", type=int, default=0)
    ap.add_argument("--tick", type=int, default=0)
    ap.add_argument("--size", default="1500,1700", help="window width,height in pixels")
    args = ap.parse_args()
    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    profile = tempfile.mkdtemp(prefix="btfsm-shot-")
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--hide-scrollbars", f"--window-size={args.size}", f"--user-data-dir={profile}"):
        opts.add_argument(flag)
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver") or "/usr/bin/chromedriver"), options=opts)
    try:
        driver.get(Path(args.report).resolve().as_uri())
        driver.execute_script("window.btfsmView.selectRun(arguments[0]); window.btfsmView.setTick(arguments[1])",
                              args.run, args.tick)
        driver.save_screenshot(args.png)
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)
    print(args.png)


if __name__ == "__main__":
    main()
