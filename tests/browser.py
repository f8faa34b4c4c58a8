"""A tiny headless-Chromium harness for the site tests; no Python dependency beyond the stdlib.

Launches Debian's ``chromium`` (or ``chromium-browser`` / ``google-chrome``) with
``--remote-debugging-pipe`` and speaks the Chrome DevTools Protocol over the pipe: the browser
reads NUL-terminated JSON messages on its fd 3 and writes them on its fd 4.

    with Browser() as b:
        result = b.check(Path("site/index.html"))      # PageCheck
        assert result.ok, result.problems()
        b.screenshot(Path("site/index.html"), Path("overview.png"), 1400, 1000, full_page=False)

``check`` loads one page in a fresh tab (every http(s) request blocked, so a test never waits on
the network) and reports console errors and uncaught exceptions, failed loads (an error or HTTP
status >= 400), every http(s) request, images that did not load, relative links whose
target is not on disk, and each shown PNG's layout verdict (compare/render/figure_check.py). Every wait is bounded: a page that does not load in ``timeout`` seconds
is reported as timed out, and the browser is killed (the next call starts a fresh one).
"""
from __future__ import annotations

import base64
import dataclasses
import fcntl
import json
import os
import queue
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

CANDIDATES = ("chromium", "chromium-browser", "google-chrome")
SKIP_REASON = "headless Chromium not installed: apt-get install chromium"
FLAGS = ("--headless=new", "--remote-debugging-pipe", "--no-sandbox", "--disable-gpu",
         "--no-first-run", "--no-default-browser-check", "--disable-background-networking",
         "--disable-component-update", "--disable-extensions", "--disable-sync",
         "--hide-scrollbars", "--mute-audio")
# images not loaded (or loaded but undecodable), and every link's raw href and resolved URL
BROKEN_IMAGES_JS = "[...document.images].filter(i => !i.complete || i.naturalWidth === 0).map(i => i.src)"
LINKS_JS = "[...document.querySelectorAll('a[href]')].map(a => [a.getAttribute('href'), a.href])"
IMAGES_JS = "[...document.images].map(i => i.src)"


def find_chromium() -> str | None:
    """The first Chromium on PATH, or None."""
    for name in CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    return None


class BrowserError(RuntimeError):
    """The browser could not be started, exited, or answered a command with an error."""


@dataclasses.dataclass
class PageCheck:
    """What loading one page showed. ``ok`` when nothing is wrong."""
    url: str
    title: str = ""
    console_errors: list[str] = dataclasses.field(default_factory=list)
    failed_loads: list[str] = dataclasses.field(default_factory=list)
    network_requests: list[str] = dataclasses.field(default_factory=list)    # http(s): must be none
    broken_images: list[str] = dataclasses.field(default_factory=list)
    broken_links: list[str] = dataclasses.field(default_factory=list)
    external_links: list[str] = dataclasses.field(default_factory=list)      # <a href="https://...">: allowed
    figure_problems: list[str] = dataclasses.field(default_factory=list)     # a shown PNG's layout
    values: dict[str, Any] = dataclasses.field(default_factory=dict)         # check(evaluate=...)'s answers
    timed_out: bool = False

    def problems(self) -> list[str]:
        out = [f"timed out loading {self.url}"] if self.timed_out else []
        for label, items in (("console error", self.console_errors), ("failed load", self.failed_loads),
                             ("network request", self.network_requests),
                             ("broken image", self.broken_images), ("broken link", self.broken_links),
                             ("figure", self.figure_problems)):
            out += [f"{label}: {x}" for x in items]
        return out

    @property
    def ok(self) -> bool:
        return not self.problems()


def file_url(path: str | Path) -> str:
    """A path as a file:// URL (a URL is returned unchanged)."""
    s = str(path)
    return s if "://" in s else Path(s).resolve().as_uri()


def local_path(url: str) -> Path | None:
    """The file a file:// URL names (without query or fragment), or None for other schemes."""
    parts = urlsplit(url)
    return Path(unquote(parts.path)) if parts.scheme == "file" else None


def _relative(href: str) -> bool:
    """A link to a file beside the page: no scheme, not protocol-relative, not only a fragment."""
    h = href.strip()
    if not h or h.startswith(("#", "//")):
        return False
    head = h.split("/", 1)[0]
    return ":" not in head


class Browser:
    """One headless Chromium for many pages; a context manager (``close`` kills it)."""

    def __init__(self, executable: str | None = None, timeout: float = 30.0) -> None:
        self.executable = executable or find_chromium()
        if not self.executable:
            raise BrowserError(SKIP_REASON)
        self.timeout = timeout
        self._proc: subprocess.Popen[bytes] | None = None

    # ---- process and pipe ---------------------------------------------------------------------
    def _start(self) -> None:
        self._tmp = Path(tempfile.mkdtemp(prefix="site-browser-"))
        to_child, self._write = os.pipe()            # the browser reads commands on its fd 3
        self._read, from_child = os.pipe()           # ... and writes answers on its fd 4
        # hand the child ends over at fds >= 10, so moving them onto 3 and 4 cannot clobber one
        a, b = (fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10) for fd in (to_child, from_child))
        os.close(to_child)
        os.close(from_child)
        # a Python trampoline puts them on 3 and 4, then execs the browser (no preexec_fn: threads)
        trampoline = ("import os, sys; os.dup2(int(sys.argv[1]), 3); os.dup2(int(sys.argv[2]), 4); "
                      "os.close(int(sys.argv[1])); os.close(int(sys.argv[2])); os.execv(sys.argv[3], sys.argv[3:])")
        cmd = [sys.executable, "-c", trampoline, str(a), str(b), self.executable, *FLAGS,
               f"--user-data-dir={self._tmp / 'profile'}", "about:blank"]
        self._stderr = open(self._tmp / "stderr.txt", "wb")
        try:
            self._proc = subprocess.Popen(cmd, pass_fds=(a, b), stdin=subprocess.DEVNULL,
                                          stdout=self._stderr, stderr=self._stderr, start_new_session=True)
        finally:
            os.close(a)
            os.close(b)
        self._ids = 0
        self._queue: queue.Queue[dict[str, Any] | None] = queue.Queue()
        self._pending: list[dict[str, Any]] = []     # events read while waiting for an answer
        threading.Thread(target=self._reader, args=(self._read, self._queue), daemon=True).start()
        self.call("Browser.getVersion", timeout=max(self.timeout, 60))   # answers once the browser is up

    @staticmethod
    def _reader(fd: int, q: "queue.Queue[dict[str, Any] | None]") -> None:
        buf = b""
        while True:
            try:
                chunk = os.read(fd, 1 << 16)
            except OSError:
                chunk = b""
            if not chunk:
                q.put(None)                          # the browser is gone
                return
            buf += chunk
            *messages, buf = buf.split(b"\0")
            for m in messages:
                q.put(json.loads(m))

    def _stderr_tail(self) -> str:
        try:
            return (self._tmp / "stderr.txt").read_text(errors="replace")[-2000:]
        except OSError:
            return ""

    def _next(self, deadline: float) -> dict[str, Any]:
        try:
            msg = self._queue.get(timeout=max(0.0, deadline - time.monotonic()))
        except queue.Empty:
            raise TimeoutError from None
        if msg is None:
            raise BrowserError(f"{self.executable} exited: {self._stderr_tail()}")
        return msg

    def call(self, method: str, params: dict[str, Any] | None = None, session: str | None = None,
             timeout: float | None = None) -> dict[str, Any]:
        """Send one command and wait for its answer (events meanwhile are kept for ``events``)."""
        if self._proc is None:
            self._start()
        self._ids += 1
        msg: dict[str, Any] = {"id": self._ids, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._write, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + (timeout or self.timeout)
        while True:
            reply = self._next(deadline)
            if reply.get("id") == self._ids:
                if "error" in reply:
                    raise BrowserError(f"{method}: {reply['error'].get('message')}")
                return reply.get("result", {})
            self._pending.append(reply)

    def _wait_event(self, method: str, session: str, deadline: float) -> None:
        while not any(e.get("method") == method and e.get("sessionId") == session for e in self._pending):
            self._pending.append(self._next(deadline))

    def close(self) -> None:
        """Ask the browser to quit, then kill its process group whatever it did; idempotent."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            os.write(self._write, json.dumps({"id": 0, "method": "Browser.close"}).encode() + b"\0")
            proc.wait(timeout=5)
        except (OSError, subprocess.TimeoutExpired):
            pass
        try:
            os.killpg(proc.pid, signal.SIGKILL)      # the renderers and helpers it started
        except (ProcessLookupError, PermissionError):
            pass
        proc.wait()
        for fd in (self._write, self._read):
            try:
                os.close(fd)
            except OSError:
                pass
        self._stderr.close()
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> "Browser":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ---- pages --------------------------------------------------------------------------------
    def _open(self, url: str, deadline: float, width: int = 1400, height: int = 1000) -> tuple[str, str, str | None]:
        """A fresh tab with the domains on, navigated to ``url`` and loaded:
        (target id, session id, navigation error or None)."""
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Runtime", "Log", "Network", "Page"):
            self.call(f"{domain}.enable", session=session)
        try:     # never wait on the network (an experimental command: a browser without it still reports)
            self.call("Network.setBlockedURLs", {"urls": ["http://*", "https://*"]}, session=session)
        except BrowserError:
            pass
        self.call("Emulation.setDeviceMetricsOverride",
                  {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}, session=session)
        self._pending = [e for e in self._pending if e.get("sessionId") != session]
        nav = self.call("Page.navigate", {"url": url}, session=session,
                        timeout=max(0.1, deadline - time.monotonic()))
        self._wait_event("Page.loadEventFired", session, deadline)
        return target, session, nav.get("errorText")

    def _evaluate(self, expression: str, session: str, deadline: float) -> Any:
        r = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True}, session=session,
                      timeout=max(0.1, deadline - time.monotonic()))
        return r.get("result", {}).get("value")

    def check(self, page: str | Path, timeout: float | None = None, settle: float = 0.1,
              evaluate: dict[str, str] | None = None) -> PageCheck:
        """Load ``page`` (a path or URL) and report what went wrong; see PageCheck. ``evaluate``
        names JavaScript expressions whose JSON values land in ``values`` under the same names."""
        url = file_url(page)
        result = PageCheck(url)
        deadline = time.monotonic() + (timeout or self.timeout)
        try:
            target, session, nav_error = self._open(url, deadline)
            if nav_error:
                result.failed_loads.append(f"{url}: {nav_error}")
            time.sleep(settle)                        # errors of scripts run right after load
            result.broken_images = self._evaluate(BROKEN_IMAGES_JS, session, deadline) or []
            links = self._evaluate(LINKS_JS, session, deadline) or []
            images = self._evaluate(IMAGES_JS, session, deadline) or []
            result.title = self._evaluate("document.title", session, deadline) or ""
            for name, expression in (evaluate or {}).items():
                result.values[name] = self._evaluate(expression, session, deadline)
            self._drain()
            self.call("Target.closeTarget", {"targetId": target})
        except TimeoutError:
            result.timed_out = True
            self.close()                              # a hung page may hang the browser: start afresh
            return result
        events = [e for e in self._pending if e.get("sessionId") == session]
        self._pending = [e for e in self._pending if e.get("sessionId") != session]
        self._collect(events, result)
        result.failed_loads = list(dict.fromkeys(result.failed_loads))   # navigate and Network both report a missing page
        result.figure_problems = figure_problems(images)
        for raw, resolved in links:
            if _relative(raw):
                path = local_path(resolved)
                if path is None or not path.exists():
                    result.broken_links.append(raw)
            elif urlsplit(raw).scheme in ("http", "https"):
                result.external_links.append(raw)
        return result

    def _drain(self) -> None:
        """Events already sent but not yet read (a console error logged just before the check)."""
        while True:
            try:
                msg = self._queue.get_nowait()
            except queue.Empty:
                return
            if msg is None:
                raise BrowserError(f"{self.executable} exited: {self._stderr_tail()}")
            self._pending.append(msg)

    @staticmethod
    def _collect(events: list[dict[str, Any]], result: PageCheck) -> None:
        urls: dict[str, str] = {}
        for e in events:
            m, p = e.get("method"), e.get("params", {})
            if m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
                args = p.get("args", [])
                result.console_errors.append(" ".join(str(a.get("value", a.get("description", ""))) for a in args))
            elif m == "Runtime.exceptionThrown":
                d = p.get("exceptionDetails", {})
                result.console_errors.append(d.get("exception", {}).get("description") or d.get("text", ""))
            elif m == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
                entry = p["entry"]
                result.console_errors.append(f"{entry.get('text', '')} {entry.get('url', '')}".strip())
            elif m == "Network.requestWillBeSent":
                u = p.get("request", {}).get("url", "")
                urls[p.get("requestId", "")] = u
                if urlsplit(u).scheme in ("http", "https", "ws", "wss"):
                    result.network_requests.append(u)
            elif m == "Network.loadingFailed":
                u = urls.get(p.get("requestId", ""), "?")
                why = p.get("errorText") or p.get("blockedReason") or "failed"
                result.failed_loads.append(f"{u}: {why}")
            elif m == "Network.responseReceived" and p.get("response", {}).get("status", 0) >= 400:
                r = p["response"]
                result.failed_loads.append(f"{r.get('url', '?')}: HTTP {r.get('status')}")

    def screenshot(self, page: str | Path, out: str | Path, width: int = 1400, height: int = 1000,
                   full_page: bool = False, timeout: float | None = None) -> Path:
        """A PNG of ``page`` at a ``width`` x ``height`` viewport (the whole page when
        ``full_page``), written to ``out``."""
        deadline = time.monotonic() + (timeout or self.timeout)
        try:
            target, session, nav_error = self._open(file_url(page), deadline, width, height)
            if nav_error:
                raise BrowserError(f"{page}: {nav_error}")
            params: dict[str, Any] = {"format": "png"}
            if full_page:
                size = self.call("Page.getLayoutMetrics", session=session)["cssContentSize"]
                params.update(captureBeyondViewport=True,
                              clip={"x": 0, "y": 0, "width": width, "height": max(height, size["height"]), "scale": 1})
            data = self.call("Page.captureScreenshot", params, session=session,
                             timeout=max(0.1, deadline - time.monotonic()))["data"]
            self.call("Target.closeTarget", {"targetId": target})
        except TimeoutError:
            self.close()
            raise BrowserError(f"timed out taking a screenshot of {page}") from None
        self._pending = [e for e in self._pending if e.get("sessionId") != session]
        out = Path(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(base64.b64decode(data))
        return out


def figure_problems(srcs: list[str]) -> list[str]:
    """The layout problems of the PNGs a page shows, as stamped where they were saved
    (compare/render/figure_check.py: texts inside the canvas, no two overlapping, no legend over
    data); a PNG saved without that check is a problem too."""
    from compare.render import figure_check  # the standard library only, at import
    out = []
    for src in dict.fromkeys(srcs):
        path = local_path(src)
        if path is None or path.suffix.lower() != ".png" or not path.is_file():
            continue                          # not a local PNG, or broken (reported as such)
        found = figure_check.read(path)
        if found is None:
            out.append(f"{path.name}: layout never checked (saved without compare.render.figure_check)")
        out += [f"{path.name}: {p}" for p in found or ()]
    return out


def check_pages(pages: list[Path], timeout: float = 30.0) -> dict[Path, PageCheck]:
    """Every page loaded in one browser."""
    with Browser(timeout=timeout) as b:
        return {p: b.check(p) for p in pages}


def screenshot(page: str | Path, out: str | Path, width: int = 1400, height: int = 1000,
               full_page: bool = False, timeout: float = 30.0) -> Path:
    """One screenshot in a browser of its own (README's overview is drawn by the site build instead:
    compare.site.pages.matrix_png)."""
    with Browser(timeout=timeout) as b:
        return b.screenshot(page, out, width, height, full_page)
