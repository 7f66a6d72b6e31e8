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


def _run_browser(browser: str, url: str, png: Path, size: str, timing: list[str],
                 timeout_s: float) -> bool:
    with tempfile.TemporaryDirectory() as profile:
        proc = subprocess.Popen(
            [browser, "--headless=new", "--no-sandbox", "--disable-gpu",
             "--disable-dev-shm-usage", "--use-angle=swiftshader",
             "--enable-unsafe-swiftshader", "--disable-background-networking",
             "--disable-component-update", "--disable-sync", "--no-first-run",
             "--disable-breakpad", "--disable-crash-reporter",
             f"--user-data-dir={profile}", f"--screenshot={png}", f"--window-size={size}",
             *timing, url],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return Path(png).is_file()


def screenshot(browser: str, html: Path, png: Path, *, size: str = "800,600",
               virtual_time_ms: int = 3000) -> bool:
    """Render ``html`` (``virtual_time_ms`` of virtual time: the recording's animation plays
    from its start) and write a ``size`` screenshot to ``png``; True when it was written.

    A headless browser occasionally hangs at start-up or under virtual time on a loaded
    machine (seen once in CI: two 90 s hangs in a row); the attempts alternate virtual time
    with a real-time budget (``--timeout``), which does not depend on the virtual-time clock."""
    url = Path(html).as_uri()
    timings = ([f"--virtual-time-budget={virtual_time_ms}"],
               [f"--timeout={max(virtual_time_ms, 5000)}"],
               [f"--virtual-time-budget={virtual_time_ms}"])
    for timing in timings:
        if _run_browser(browser, url, png, size, timing, timeout_s=60):
            return True
    return False


def browser_can_screenshot(browser: str, tmp: Path) -> bool:
    """Whether this machine's browser can screenshot a trivial page at all: tells a browser
    that cannot run here (skip) from a recording that does not render (fail)."""
    page = Path(tmp) / "trivial.html"
    page.write_text("<html><body style='background:#0f0'>ok</body></html>")
    return _run_browser(browser, page.as_uri(), Path(tmp) / "trivial.png", "200,200",
                        ["--timeout=2000"], timeout_s=60)


def screenshot_or_skip(browser: str, html: Path, png: Path, **kw) -> None:
    """``screenshot``, skipping the calling test when the browser cannot screenshot even a
    trivial page on this machine (an environment problem, not a rendering failure)."""
    import pytest

    if screenshot(browser, html, png, **kw):
        return
    if not browser_can_screenshot(browser, Path(png).parent):
        pytest.skip("the headless browser cannot screenshot even a trivial page here")
    raise AssertionError("the browser screenshots a trivial page but wrote no screenshot "
                         f"of {html}")
