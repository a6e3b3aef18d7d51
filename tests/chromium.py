"""Look at a report in a real browser: headless Chromium, no network (a test helper).

The report tests use it (and it is handy by hand, from the repository) to check that a
report renders:
:func:`browser_check` loads the file with ``--dump-dom`` and reads what the
report's inline self-check script wrote after the load event (images whose
``naturalWidth`` is above zero, errors caught by the page) and the console
messages Chromium logs to stderr; :func:`screenshot` takes a PNG at a given
window size.  Chromium runs with background networking, component updates,
sync and QUIC off and a fresh profile, so it makes no request of its own; the
report's Content-Security-Policy keeps the page from making any.

:class:`BrowserSession` drives the same Chromium over the DevTools protocol
on a pipe (``--remote-debugging-pipe``: no port, nothing listens): open a
page at a window width, evaluate JavaScript, click at a point or on an
element with real mouse events, take a screenshot, and read every console
message and uncaught exception.

Needs Debian's ``chromium`` package (``/usr/bin/chromium``).
"""

from __future__ import annotations

import base64
import json
import os
import re
import select
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

__all__ = [
    "BrowserCheck",
    "BrowserSession",
    "find_chromium",
    "browser_check",
    "screenshot",
    "CHROMIUM_FLAGS",
]

#: Flags for a quiet, offline, throw-away headless Chromium.
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-default-apps",
    "--disable-extensions",
    "--no-first-run",
    "--no-default-browser-check",
    "--hide-scrollbars",
    "--mute-audio",
]

_CONSOLE = re.compile(r":CONSOLE[:(]\d*\)?\]?\s*(.*)$")


def find_chromium() -> str | None:
    """Path of a Chromium binary (``$TERRACONE_CHROMIUM``, /usr/bin/chromium, PATH) or None."""
    cand = [os.environ.get("TERRACONE_CHROMIUM"), "/usr/bin/chromium"]
    cand += [shutil.which(n) for n in ("chromium", "chromium-browser")]
    for c in cand:
        if c and Path(c).exists() and os.access(c, os.X_OK):
            return c
    return None


@dataclass
class BrowserCheck:
    """What a headless browser saw of a page.

    Attributes
    ----------
    images_ok, images_total : int or None
        Images with naturalWidth > 0, and all images, as counted by the
        page's self-check after load (None if the page has no self-check).
    page_errors : int or None
        Errors the page's self-check caught (script errors, failed loads,
        content-security-policy violations).
    page_error_text : str
        Their text.
    console : list of str
        Console messages Chromium logged (any level).
    returncode : int
    stderr : str
    page_width, view_width : int or None
        Width of the page's content and of the window [CSS px], as the
        self-check saw them: ``page_width > view_width`` means the page
        scrolls sideways.
    """

    images_ok: int | None
    images_total: int | None
    page_errors: int | None
    page_error_text: str
    console: list[str] = field(default_factory=list)
    returncode: int = 0
    stderr: str = ""
    page_width: int | None = None
    view_width: int | None = None

    @property
    def ok(self) -> bool:
        return (
            self.returncode == 0
            and self.images_total is not None
            and self.images_ok == self.images_total
            and self.page_errors == 0
            and not self.console
        )


class _SelfCheck(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.attrs: dict[str, str | None] | None = None
        self._in = False
        self.text = ""

    def handle_starttag(self, tag, attrs):
        d = dict(attrs)
        if d.get("id") == "tc-selfcheck":
            self.attrs = d
            self._in = True

    def handle_endtag(self, tag):
        if self._in and tag == "p":
            self._in = False

    def handle_data(self, data):
        if self._in:
            self.text += data


def _int(v: str | None) -> int | None:
    try:
        return int(v) if v not in (None, "") else None
    except ValueError:
        return None


def _run(args: list[str], timeout: float) -> subprocess.CompletedProcess:
    exe = find_chromium()
    if exe is None:
        raise FileNotFoundError("Chromium not found (install Debian's chromium package)")
    with tempfile.TemporaryDirectory(prefix="terracone-chromium-") as profile:
        cmd = [exe, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args]
        return subprocess.run(
            cmd, capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL
        )


def browser_check(path: str | Path, *, timeout: float = 120.0, width: int = 1280) -> BrowserCheck:
    """Load ``path`` in headless Chromium and report what it rendered.

    Uses ``--dump-dom`` (the DOM after the load event, with a virtual time
    budget so the self-check script has run) and ``--enable-logging=stderr
    --v=0`` (console messages).
    """
    url = Path(path).resolve().as_uri()
    res = _run(
        [
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=10000",
            f"--window-size={width},2000",
            "--dump-dom",
            url,
        ],
        timeout,
    )
    parser = _SelfCheck()
    parser.feed(res.stdout)
    a = parser.attrs or {}
    console = []
    for line in res.stderr.splitlines():
        m = _CONSOLE.search(line)
        if m and "CONSOLE" in line:
            console.append(m.group(1).strip())
    return BrowserCheck(
        images_ok=_int(a.get("data-images-ok")),
        images_total=_int(a.get("data-images-total")),
        page_errors=_int(a.get("data-errors")),
        page_error_text=parser.text.strip(),
        console=console,
        returncode=res.returncode,
        stderr=res.stderr,
        page_width=_int(a.get("data-page-width")),
        view_width=_int(a.get("data-view-width")),
    )


def screenshot(
    path: str | Path, out_png: str | Path, *, width: int, height: int, timeout: float = 120.0
) -> Path:
    """Screenshot of ``path`` at a window of ``width`` x ``height`` CSS pixels."""
    out = Path(out_png).resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    res = _run(
        [
            f"--window-size={width},{height}",
            "--virtual-time-budget=10000",
            f"--screenshot={out}",
            Path(path).resolve().as_uri(),
        ],
        timeout,
    )
    if res.returncode != 0 or not out.exists():
        raise RuntimeError(f"chromium screenshot failed ({res.returncode}): {res.stderr[-2000:]}")
    return out


class BrowserSession:
    """Headless Chromium driven over the DevTools protocol on a pipe.

    Parameters
    ----------
    width, height : int
        Window (viewport) size [CSS px].
    timeout : float
        Seconds to wait for any one reply of the browser [s].

    Examples
    --------
    >>> with BrowserSession(width=390, height=800) as b:  # doctest: +SKIP
    ...     b.open("report.html")
    ...     b.evaluate("document.documentElement.scrollWidth")
    ...     b.click_selector("#tbl-profiles th[data-col='2'] button")
    ...     b.screenshot("phone.png")

    ``console`` holds every console message (``"level: text"``), uncaught
    exception and browser log entry seen since the session began.
    """

    def __init__(self, *, width: int = 1280, height: int = 900, timeout: float = 60.0) -> None:
        exe = find_chromium()
        if exe is None:
            raise FileNotFoundError("Chromium not found (install Debian's chromium package)")
        self.timeout = float(timeout)
        self.console: list[str] = []
        self._events: list[dict[str, Any]] = []
        self._buf = b""
        self._id = 0
        self._profile = tempfile.TemporaryDirectory(prefix="terracone-chromium-")
        to_chrome_r, self._to_chrome = os.pipe()
        self._from_chrome, from_chrome_w = os.pipe()

        def _fds() -> None:  # in the child: fd 3 reads commands, fd 4 writes replies
            os.dup2(to_chrome_r, 3)
            os.dup2(from_chrome_w, 4)

        self._proc = subprocess.Popen(
            [
                exe,
                *CHROMIUM_FLAGS,
                "--remote-debugging-pipe",
                f"--user-data-dir={self._profile.name}",
                f"--window-size={width},{height}",
                "about:blank",
            ],
            pass_fds=(3, 4),
            preexec_fn=_fds,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        try:
            target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
            self._session = self.call(
                "Target.attachToTarget", {"targetId": target, "flatten": True}
            )["sessionId"]
            for domain in ("Page", "Runtime", "Log"):
                self.call(f"{domain}.enable", session=True)
            self.set_viewport(width, height)
        except Exception:
            self.close()
            raise

    # -- protocol ------------------------------------------------------------

    def _send(self, method: str, params: dict[str, Any] | None, session: bool) -> int:
        self._id += 1
        msg: dict[str, Any] = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = self._session
        os.write(self._to_chrome, json.dumps(msg).encode() + b"\0")
        return self._id

    def _next(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            ready, _, _ = select.select([self._from_chrome], [], [], max(0.0, left))
            if not ready:
                raise TimeoutError(f"Chromium did not answer within {self.timeout:g} s")
            chunk = os.read(self._from_chrome, 1 << 20)
            if not chunk:
                raise RuntimeError("Chromium closed the DevTools pipe")
            self._buf += chunk
        raw, self._buf = self._buf.split(b"\0", 1)
        msg = json.loads(raw)
        if "method" in msg:
            self._note(msg)
        return msg

    def _note(self, ev: dict[str, Any]) -> None:
        m, p = ev["method"], ev.get("params", {})
        if m == "Runtime.consoleAPICalled":
            text = " ".join(
                str(a.get("value", a.get("description", ""))) for a in p.get("args", [])
            )
            self.console.append(f"{p.get('type')}: {text}")
        elif m == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            self.console.append(
                f"exception: {d.get('exception', {}).get('description') or d.get('text')}"
            )
        elif m == "Log.entryAdded":
            e = p.get("entry", {})
            self.console.append(f"{e.get('level')}: {e.get('text')}")
        self._events.append(ev)

    def call(self, method: str, params: dict[str, Any] | None = None, *, session: bool = False):
        """Send one DevTools command and return its result (``session``: to the page)."""
        i = self._send(method, params, session)
        deadline = time.monotonic() + self.timeout
        while True:
            msg = self._next(deadline)
            if msg.get("id") == i:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error'].get('message')}")
                return msg.get("result", {})

    def _wait_event(self, method: str) -> dict[str, Any]:
        deadline = time.monotonic() + self.timeout
        while True:
            for k, ev in enumerate(self._events):
                if ev["method"] == method:
                    del self._events[: k + 1]
                    return ev
            self._events.clear()
            self._next(deadline)

    # -- page ----------------------------------------------------------------

    def set_viewport(self, width: int, height: int) -> None:
        """Viewport of ``width`` x ``height`` CSS px (mobile layout below 640 px)."""
        self.call(
            "Emulation.setDeviceMetricsOverride",
            {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": width < 640},
            session=True,
        )

    def open(self, path_or_url: str | Path) -> None:
        """Load a file (or URL) and wait for its load event."""
        s = str(path_or_url)
        url = s if re.match(r"^[a-z]+:", s) else Path(s).resolve().as_uri()
        self._events.clear()
        res = self.call("Page.navigate", {"url": url}, session=True)
        if res.get("errorText"):
            raise RuntimeError(f"cannot open {url}: {res['errorText']}")
        self._wait_event("Page.loadEventFired")

    def evaluate(self, expression: str) -> Any:
        """Value of a JavaScript expression in the page (JSON-serialisable)."""
        res = self.call(
            "Runtime.evaluate",
            {"expression": expression, "returnByValue": True, "awaitPromise": True},
            session=True,
        )
        if "exceptionDetails" in res:
            d = res["exceptionDetails"]
            raise RuntimeError(f"JavaScript error: {d.get('exception', {}).get('description')}")
        return res.get("result", {}).get("value")

    def click(self, x: float, y: float) -> None:
        """A left mouse click at viewport point (x, y) [CSS px]."""
        for kind in ("mouseMoved", "mousePressed", "mouseReleased"):
            self.call(
                "Input.dispatchMouseEvent",
                {"type": kind, "x": x, "y": y, "button": "left", "clickCount": 1},
                session=True,
            )

    def click_selector(self, selector: str) -> None:
        """Scroll the first element matching ``selector`` into view and click its centre."""
        box = self.evaluate(
            "(function(){var el=document.querySelector(" + json.dumps(selector) + ");"
            "if(!el){return null;} el.scrollIntoView({block:'center',inline:'center'});"
            "var r=el.getBoundingClientRect(); return [r.left+r.width/2, r.top+r.height/2];})()"
        )
        if box is None:
            raise ValueError(f"no element matches {selector!r}")
        self.click(float(box[0]), float(box[1]))

    def screenshot(self, out_png: str | Path, *, full_page: bool = False) -> Path:
        """PNG of the viewport (or of the whole page) [file path]."""
        params: dict[str, Any] = {"format": "png"}
        if full_page:
            params["captureBeyondViewport"] = True
        data = self.call("Page.captureScreenshot", params, session=True)["data"]
        out = Path(out_png)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(base64.b64decode(data))
        return out

    def close(self) -> None:
        """End the browser and remove its throw-away profile."""
        try:
            if self._proc.poll() is None:
                try:
                    self._send("Browser.close", None, False)
                    self._proc.wait(timeout=10)
                except (OSError, subprocess.TimeoutExpired):
                    self._proc.kill()
                    self._proc.wait(timeout=10)
        finally:
            for fd in (self._to_chrome, self._from_chrome):
                try:
                    os.close(fd)
                except OSError:
                    pass
            self._profile.cleanup()

    def __enter__(self) -> BrowserSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
