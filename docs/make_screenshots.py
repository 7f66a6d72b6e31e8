"""Regenerate the documentation's screenshots: one per capability, each taken in headless
Chromium from the Meshcat recording (``--html-out``) of a real run of that capability's app.

    python docs/make_screenshots.py                      # all six, into docs/images/
    python docs/make_screenshots.py --only door,tactile  # some of them
    python docs/make_screenshots.py --keep-html DIR      # also keep the recordings

Needs a Chromium (``chromium``, ``chromium-browser`` or ``google-chrome`` on the PATH;
Debian: ``apt-get install chromium``). Each run is the app's own command line (below, with
its seed); the recording's animation plays in the browser for ``virtual_ms`` of virtual
time before the screenshot, which shows the scene at that moment with its legend. Images
are written atomically (a temporary file, then a rename), 1000 x 650 pixels. Takes about
10 minutes on two cores (the body-schema and imitation runs are the longest).
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SIZE = "1000,650"

#: name -> (the app and its arguments, virtual time to play the recording, ms). The
#: screenshot shows the recording at that time: the end of the motion; for the fronts the
#: door half open (the 30 frames' point clouds make the page slow to play); mid-hold for
#: the tactile grasp (the recording plays ahead of the virtual clock: 1000 ms shows about
#: 1.7 s of the grasp, near its peak force; the readings are back to 0 after the release).
SHOTS = {
    "door": (["mmlearn.apps.open_cabinet", "--object", "left_door", "--seed", "1"], 30000),
    "drawer": (["mmlearn.apps.open_cabinet", "--object", "drawer", "--seed", "1"], 30000),
    "fronts": (["mmlearn.apps.track_fronts", "--object", "door", "--distance", "1.5",
                "--frames", "30", "--seed", "1"], 10000),
    "body_schema": (["mmlearn.apps.learn_body_schema", "--arm", "4dof", "--seed", "1",
                     "--n-control", "3"], 60000),
    "imitation": (["mmlearn.apps.imitate", "--task", "pick_place", "--demos", "4",
                   "--seed", "3"], 60000),
    "tactile": (["mmlearn.apps.tactile_state", "--f-target", "20", "--containers", "odwalla",
                 "--trials", "2", "--folds", "2", "--seed", "3"], 1000),
}


def chromium() -> str | None:
    """The browser's executable, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return shutil.which(name)
    return None


def record(name: str, html: Path) -> float:
    """Run the app of ``name`` with ``--html-out html``; returns its wall time, s."""
    args, _ = SHOTS[name]
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", *args, "--html-out", str(html)],
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                       env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    # open_cabinet exits 1 when the mechanism was not opened: still a recording
    if not html.is_file():
        tail = " ".join(r.stderr.strip().splitlines()[-1:])
        raise RuntimeError(f"{name}: {' '.join(args)} wrote no recording (exit {r.returncode}"
                           f"{': ' + tail if tail else ''})")
    return time.perf_counter() - t0


def screenshot(browser: str, html: Path, png: Path, virtual_ms: int) -> None:
    """Screenshot ``html`` after ``virtual_ms`` of virtual time into ``png`` (atomically)."""
    tmp = png.with_name(f".{png.stem}.tmp.png")
    tmp.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory() as profile:
        for attempt in range(3):  # a headless browser occasionally hangs at start-up
            proc = subprocess.Popen(
                [browser, "--headless=new", "--no-sandbox", "--disable-gpu",
                 "--disable-dev-shm-usage", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader", "--hide-scrollbars", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update",
                 f"--user-data-dir={profile}", f"--screenshot={tmp}", f"--window-size={SIZE}",
                 f"--virtual-time-budget={virtual_ms}", html.resolve().as_uri()],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
            try:
                proc.wait(timeout=240 + virtual_ms / 1000)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            if tmp.is_file():
                os.replace(tmp, png)
                return
    raise RuntimeError(f"the browser wrote no screenshot of {html}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python docs/make_screenshots.py",
                                 description="Regenerate the screenshots of the docs from "
                                             "real Meshcat recordings.")
    ap.add_argument("--only", default=",".join(SHOTS),
                    help=f"comma-separated names (default: all of {', '.join(SHOTS)})")
    ap.add_argument("--out-dir", type=Path, default=HERE / "images")
    ap.add_argument("--keep-html", type=Path, default=None, metavar="DIR",
                    help="also keep the recordings in DIR")
    args = ap.parse_args(argv)
    names = [n.strip() for n in args.only.split(",") if n.strip()]
    bad = [n for n in names if n not in SHOTS]
    if bad or not names:
        print(f"{ap.prog}: error: --only: unknown {', '.join(bad) or 'empty list'} "
              f"(known: {', '.join(SHOTS)})", file=sys.stderr)
        return 2
    browser = chromium()
    if browser is None:
        print(f"{ap.prog}: error: no chromium on the PATH (apt-get install chromium)",
              file=sys.stderr)
        return 2
    for d in (args.out_dir, args.keep_html):
        if d is not None:
            d.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="mmlearn_shots_") as tmp:
        for name in names:
            html = (args.keep_html or Path(tmp)) / f"{name}.html"
            wall = record(name, html)
            png = args.out_dir / f"{name}.png"
            screenshot(browser, html, png, SHOTS[name][1])
            print(f"{png}: {png.stat().st_size // 1024} KB (run {wall:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
