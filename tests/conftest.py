"""Test-wide setup: a private Xvfb display for GUI tests, and headless-safe Qt/VTK settings.

GUI tests need a real X server (they show real windows, and ``--screenshot`` refuses Qt's
offscreen platform: app/window.py ``check_display``); if DISPLAY is unset and Xvfb is
installed, one is started for the session and stopped after.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time

import pytest

_xvfb: subprocess.Popen | None = None


def _start_xvfb() -> None:
    global _xvfb
    if os.environ.get("DISPLAY") or shutil.which("Xvfb") is None:
        return
    for num in range(90, 120):
        if os.path.exists(f"/tmp/.X11-unix/X{num}") or os.path.exists(f"/tmp/.X{num}-lock"):
            continue
        proc = subprocess.Popen(
            ["Xvfb", f":{num}", "-screen", "0", "1600x1000x24", "-nolisten", "tcp"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for _ in range(100):
            if os.path.exists(f"/tmp/.X11-unix/X{num}"):
                break
            if proc.poll() is not None:
                break
            time.sleep(0.05)
        if proc.poll() is None:
            _xvfb = proc
            os.environ["DISPLAY"] = f":{num}"
            return


def pytest_configure(config: pytest.Config) -> None:
    _start_xvfb()
    os.environ.setdefault("QT_QPA_PLATFORM", "xcb" if os.environ.get("DISPLAY") else "offscreen")
    os.environ.setdefault("OMP_NUM_THREADS", "2")


def pytest_unconfigure(config: pytest.Config) -> None:
    if _xvfb is not None:
        _xvfb.terminate()
        try:
            _xvfb.wait(timeout=5)
        except subprocess.TimeoutExpired:
            _xvfb.kill()
