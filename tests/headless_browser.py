"""Screenshots of a standalone Meshcat recording in a real headless browser (Debian's
chromium; ``.ci/run`` installs it). Shared by the tests that look at rendered recordings."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import tempfile
from pathlib import Path


def chromium() -> str | None:
    """The browser's executable, or None when there is none on this machine."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return shutil.which(name)
    return None


def screenshot(browser: str, html: Path, png: Path, *, size: str = "800,600",
               virtual_time_ms: int = 3000) -> bool:
    """Render ``html`` (``virtual_time_ms`` of virtual time: the recording's animation plays
    from its start) and write a ``size`` screenshot to ``png``; True when it was written."""
    for attempt in range(2):  # a headless browser occasionally hangs at start-up: retry once
        with tempfile.TemporaryDirectory() as profile:
            proc = subprocess.Popen(
                [browser, "--headless=new", "--no-sandbox", "--disable-gpu",
                 "--disable-dev-shm-usage", "--use-angle=swiftshader",
                 "--enable-unsafe-swiftshader", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run",
                 f"--user-data-dir={profile}", f"--screenshot={png}", f"--window-size={size}",
                 f"--virtual-time-budget={virtual_time_ms}", Path(html).as_uri()],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
            try:
                proc.wait(timeout=90)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        if Path(png).is_file():
            return True
    return False
