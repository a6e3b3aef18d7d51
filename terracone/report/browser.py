"""Look at a report in a real browser: headless Chromium, no network.

Used by the tests (and handy by hand) to check that a report renders:
:func:`browser_check` loads the file with ``--dump-dom`` and reads what the
report's inline self-check script wrote after the load event (images whose
``naturalWidth`` is above zero, errors caught by the page) and the console
messages Chromium logs to stderr; :func:`screenshot` takes a PNG at a given
window size.  Chromium runs with background networking, component updates,
sync and QUIC off and a fresh profile, so it makes no request of its own; the
report's Content-Security-Policy keeps the page from making any.

Needs Debian's ``chromium`` package (``/usr/bin/chromium``).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path

__all__ = ["BrowserCheck", "find_chromium", "browser_check", "screenshot", "CHROMIUM_FLAGS"]

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
    """

    images_ok: int | None
    images_total: int | None
    page_errors: int | None
    page_error_text: str
    console: list[str] = field(default_factory=list)
    returncode: int = 0
    stderr: str = ""

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


def browser_check(path: str | Path, *, timeout: float = 120.0) -> BrowserCheck:
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
            "--window-size=1280,2000",
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
