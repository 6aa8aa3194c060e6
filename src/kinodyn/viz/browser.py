"""Open a viewer page in headless Chromium and watch it play (tests, benchmarks, screenshots).

Uses the system's Chromium and chromedriver (Debian: ``apt-get install chromium chromium-driver``)
through Selenium; nothing is downloaded. WebGL runs on SwiftShader (software), so frame rates measured
here are a lower bound of what a desktop browser with a GPU reaches.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

from kinodyn.errors import KinodynError

__all__ = ["PageCheck", "check_page", "chromium", "find_chromium", "unavailable_reason"]

_CHROMIUM = ("/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome")
_DRIVER = ("/usr/bin/chromedriver", "/usr/lib/chromium/chromedriver")


class BrowserUnavailableError(KinodynError, RuntimeError):
    """Headless Chromium, chromedriver or Selenium is not installed."""


def find_chromium() -> tuple[str | None, str | None]:
    """Paths of the Chromium binary and chromedriver (``KINODYN_CHROMIUM`` / ``KINODYN_CHROMEDRIVER``
    override), or ``None`` where absent."""
    def first(env, cands, name):
        p = os.environ.get(env)
        if p:
            return p if Path(p).is_file() else None
        for c in cands:
            if Path(c).is_file():
                return c
        return shutil.which(name)

    return first("KINODYN_CHROMIUM", _CHROMIUM, "chromium"), first("KINODYN_CHROMEDRIVER", _DRIVER, "chromedriver")


def unavailable_reason() -> str | None:
    """Why a headless browser cannot be started here, or ``None`` when it can."""
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed (pip install 'kinodyn[dev]')"
    browser, driver = find_chromium()
    if browser is None:
        return "Chromium is not installed (apt-get install chromium chromium-driver)"
    if driver is None:
        return "chromedriver is not installed (apt-get install chromium-driver)"
    return None


@contextlib.contextmanager
def chromium(width: int = 1280, height: int = 720, args: tuple[str, ...] = ()):
    """A headless Chromium WebDriver with software WebGL and browser-console logging.

    Args:
        args: more Chromium switches (``("--disable-webgl",)`` shows a page as a browser without WebGL).
    """
    reason = unavailable_reason()
    if reason:
        raise BrowserUnavailableError(reason)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    browser, driver_path = find_chromium()
    opts = webdriver.ChromeOptions()
    opts.binary_location = browser
    for a in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", f"--window-size={width},{height}",
              "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
              "--disable-background-timer-throttling", "--disable-renderer-backgrounding",
              "--allow-file-access-from-files", "--no-first-run", "--disable-extensions", *args):
        opts.add_argument(a)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    drv = webdriver.Chrome(service=Service(executable_path=driver_path), options=opts)
    try:
        yield drv
    finally:
        drv.quit()


@dataclass(frozen=True)
class PageCheck:
    """What :func:`check_page` saw.

    Attributes:
        ready: the viewer finished loading.
        frames_advanced: scene frames played while measuring (loops included).
        distinct_frames: how many different frame numbers the counter showed when polled (10 Hz).
        fps: rendered frames per second over the measuring window.
        console_errors: SEVERE browser console messages and viewer errors.
        screenshot: PNG bytes of the page.
        total_frames: frames of the scene clock.
        load_s: seconds from navigation to ready.
    """

    ready: bool
    frames_advanced: int
    distinct_frames: int
    fps: float
    console_errors: tuple[str, ...]
    screenshot: bytes
    total_frames: int
    load_s: float


def check_page(path, seconds: float = 3.0, width: int = 1280, height: int = 720, timeout: float = 60.0,
               before_screenshot=None) -> PageCheck:
    """Load a viewer page, let it play ``seconds``, and report (see :class:`PageCheck`).

    Args:
        before_screenshot: optional JavaScript run just before the screenshot (e.g. seek to a frame).
    """
    url = Path(path).resolve().as_uri()
    with chromium(width, height) as drv:
        t0 = time.perf_counter()
        drv.get(url)
        ready = False
        while time.perf_counter() - t0 < timeout:
            ready = bool(drv.execute_script("return !!(window.kinodynViewer && window.kinodynViewer.ready)"))
            errs = drv.execute_script("return window.kinodynViewer ? window.kinodynViewer.errors.length : 0")
            if ready or errs:
                break
            time.sleep(0.05)
        load_s = time.perf_counter() - t0
        frames, fps, total, distinct = 0, 0.0, 0, 0
        if ready:
            api = "window.kinodynViewer"
            drv.execute_script(f"{api}.play()")
            p0, n0 = drv.execute_script(f"return [{api}.played || 0, {api}.renderedFrames]")
            w0 = time.perf_counter()
            seen = set()
            while time.perf_counter() - w0 < seconds:
                seen.add(drv.execute_script(f"return {api}.frame"))
                time.sleep(0.1)
            p1, n1, scene_fps = drv.execute_script(
                f"return [{api}.played || 0, {api}.renderedFrames, {api}.viewer ? {api}.viewer.fps : 0]")
            fps = (n1 - n0) / (time.perf_counter() - w0)
            total = int(drv.execute_script(f"return {api}.totalFrames"))
            frames = round((p1 - p0) * scene_fps)
            distinct = len(seen)
        if before_screenshot:
            drv.execute_script(before_screenshot)
            time.sleep(0.3)
        png = drv.get_screenshot_as_png()
        errors = [f"{e.get('level')}: {e.get('message')}" for e in drv.get_log("browser")
                  if e.get("level") == "SEVERE"]
        errors += list(drv.execute_script("return window.kinodynViewer ? window.kinodynViewer.errors : []") or [])
    return PageCheck(ready, frames, distinct, float(fps), tuple(errors), png, total, load_s)
