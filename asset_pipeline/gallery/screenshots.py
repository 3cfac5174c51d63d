"""Screenshots of the served gallery: Debian's headless Chromium driven over the DevTools
protocol (a pipe, no extra package), waiting for the page to say its 3D views have drawn.
``python -m asset_pipeline.gallery.server OUT --screenshot PNG [--query asset=ID&q=J:V]``
and ``scripts/gallery_screenshot.sh`` use it.
"""

from __future__ import annotations

import base64
import fcntl
import json
import logging
import os
import select
import shutil
import subprocess
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- screenshots

CHROMIUM = "/usr/bin/chromium"
#: Headless Chromium on a machine without a network or a GPU (WebGL runs on the CPU).
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
)
#: The page's readiness: viewer.js sets ``data-gallery-ready`` on <body> to "1" once the
#: 3D views in sight (or the one named by ``?asset=``) have drawn, "error" when it failed;
#: the page's inline script sets "file" when it was opened from the file system.
_READY_JS = "document.body ? (document.body.dataset.galleryReady || '') : ''"


class ScreenshotError(RuntimeError):
    """Chromium is missing, failed, or did not answer."""


class _DevTools:
    """The Chrome DevTools protocol over ``--remote-debugging-pipe`` (fds 3 and 4)."""

    def __init__(self, chromium: str, flags: list[str]) -> None:
        cmd_r, self._w = os.pipe()
        self._r, out_w = os.pipe()
        # the child's ends above fd 9, so that moving them to fds 3 and 4 clobbers neither
        for fd, name in ((cmd_r, "cmd_r"), (out_w, "out_w")):
            high = fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10)
            os.close(fd)
            if name == "cmd_r":
                cmd_r = high
            else:
                out_w = high
        self._buf = b""
        self._n = 0
        try:
            self.proc = subprocess.Popen(
                [
                    "/bin/bash",  # dash takes only one-digit fds in redirections
                    "-c",
                    f'exec "$0" "$@" 3<&{cmd_r} 4>&{out_w}',
                    chromium,
                    *flags,
                    "--remote-debugging-pipe",
                ],
                pass_fds=(cmd_r, out_w),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
            )
        except OSError as e:
            os.close(self._w)
            os.close(self._r)
            raise ScreenshotError(f"cannot start {chromium}: {e}") from e
        finally:
            os.close(cmd_r)
            os.close(out_w)

    def call(
        self,
        method: str,
        params: dict | None = None,
        session: str | None = None,
        timeout: float = 30,
    ) -> dict:
        self._n += 1
        msg: dict[str, Any] = {"id": self._n, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        try:
            os.write(self._w, json.dumps(msg).encode() + b"\0")
        except OSError as e:
            raise ScreenshotError(f"chromium closed its pipe ({method}): {self._stderr()}") from e
        deadline = time.monotonic() + timeout
        while True:
            reply = self._next(deadline, method)
            if reply.get("id") == self._n:
                if "error" in reply:
                    raise ScreenshotError(f"{method}: {reply['error'].get('message')}")
                return reply.get("result", {})

    def _next(self, deadline: float, method: str) -> dict:
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._r], [], [], left)[0]:
                raise ScreenshotError(f"chromium did not answer {method} in time")
            chunk = os.read(self._r, 1 << 20)
            if not chunk:
                raise ScreenshotError(f"chromium closed its pipe ({method}): {self._stderr()}")
            self._buf += chunk
        raw, _, self._buf = self._buf.partition(b"\0")
        return json.loads(raw)

    def _stderr(self) -> str:
        if self.proc.poll() is None:
            return "still running"
        err = self.proc.stderr.read().decode(errors="replace") if self.proc.stderr else ""
        lines = [x for x in err.splitlines() if "dbus" not in x and x.strip()]
        return f"exit {self.proc.returncode}: " + " | ".join(lines[-5:])

    def close(self) -> None:
        try:
            if self.proc.poll() is None:
                self.call("Browser.close", timeout=5)
        except ScreenshotError:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        for fd in (self._w, self._r):
            try:
                os.close(fd)
            except OSError:
                pass
        if self.proc.stderr:
            self.proc.stderr.close()


@dataclass
class Shot:
    """A page to photograph: ``url`` into ``png``, in a window of ``size`` (width, height;
    None: the session's); ``probe``, a JavaScript expression, is evaluated once the page
    is ready. :func:`screenshots` fills in ``state`` (the page's readiness: "1" ready,
    "error" a 3D view failed, "file" opened from the file system, "" timed out) and
    ``value`` (the probe's value)."""

    url: str
    png: str | Path
    size: tuple[int, int] | None = None
    probe: str | None = None
    state: str = ""
    value: Any = None


def screenshots(
    shots: Sequence[Shot],
    width: int = 1280,
    height: int = 2000,
    timeout: float = 60.0,
    chromium: str | None = None,
) -> list[Shot]:
    """Take every :class:`Shot` with one headless Chromium, each in a new tab; return them.

    Each page is given up to ``timeout`` seconds to say it is ready (``data-gallery-ready``
    on <body>: its 3D views drawn); the shot is taken then, or at the time-out. Raises
    :class:`ScreenshotError` when Chromium is missing or fails. Chromium runs with its
    own new, empty profile and reaches nothing but the URLs' server.
    """
    chromium = chromium or os.environ.get("CHROMIUM") or CHROMIUM
    if shutil.which(chromium) is None:
        raise ScreenshotError(f"{chromium} not found; install it with: apt-get install -y chromium")
    profile = tempfile.mkdtemp(prefix="pact-chromium-")
    flags = [*CHROMIUM_FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}"]
    dt = None
    try:
        dt = _DevTools(chromium, flags)
        for shot in shots:
            w, h = shot.size or (width, height)
            target = dt.call("Target.createTarget", {"url": "about:blank"})["targetId"]
            session = dt.call("Target.attachToTarget", {"targetId": target, "flatten": True})[
                "sessionId"
            ]
            dt.call(
                "Emulation.setDeviceMetricsOverride",
                {"width": w, "height": h, "deviceScaleFactor": 1, "mobile": False},
                session,
            )
            dt.call("Page.navigate", {"url": shot.url}, session)

            def evaluate(expression: str, session: str = session) -> Any:
                res = dt.call(
                    "Runtime.evaluate", {"expression": expression, "returnByValue": True}, session
                )
                return res.get("result", {}).get("value")

            deadline = time.monotonic() + timeout
            shot.state = ""
            while time.monotonic() < deadline:
                shot.state = str(evaluate(_READY_JS) or "")
                if shot.state:
                    break
                time.sleep(0.1)
            if shot.probe:
                shot.value = evaluate(shot.probe)
            data = dt.call("Page.captureScreenshot", {"format": "png"}, session)["data"]
            Path(shot.png).write_bytes(base64.b64decode(data))
            dt.call("Target.closeTarget", {"targetId": target})
        return list(shots)
    finally:
        if dt is not None:
            dt.close()
        shutil.rmtree(profile, ignore_errors=True)


def screenshot(
    url: str,
    png: str | Path,
    width: int = 1280,
    height: int = 2000,
    timeout: float = 60.0,
    chromium: str | None = None,
) -> str:
    """One shot of :func:`screenshots`; returns the page's readiness (:class:`Shot`)."""
    return screenshots([Shot(url, png)], width, height, timeout, chromium)[0].state


# --------------------------------------------------------------------------- command line
