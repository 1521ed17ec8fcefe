"""Drive headless Chromium from the tests: open a local page, evaluate JavaScript, take screenshots.

A test tool, not part of the extension. Chromium comes from Debian's ``chromium`` package
(``tools/ensure_chromium.sh`` installs it; ``make test`` runs that script first). The browser is
driven through the Chrome DevTools Protocol over ``--remote-debugging-pipe``: JSON messages,
each ended by a NUL byte, on the child's file descriptors 3 (commands in) and 4 (replies and
events out). That needs nothing beyond the standard library.

Every run starts Chromium with a fresh profile folder and the flags that keep it off the
network (no first-run, sync, component update, background networking or QUIC), so a page can
only load what it finds on disk.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import queue
import shutil
import subprocess
import tempfile
import threading
import time

FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--remote-debugging-pipe",
)

#: Executable names of Debian's package (and of other distributions, for a developer's machine).
EXECUTABLES = ("chromium", "chromium-browser")


def find_chromium() -> str | None:
    for name in EXECUTABLES:
        path = shutil.which(name)
        if path:
            return path
    return None


class BrowserError(RuntimeError):
    """Chromium failed, or answered a command with an error."""


class Page:
    """What one page load produced: console errors, failed requests, uncaught exceptions."""

    def __init__(self, browser: Chromium, session: str, width: int):
        self.browser = browser
        self.session = session
        self.width = width  # of the viewport, CSS pixels
        self.console: list[str] = []  # console.error/warn messages and exceptions
        self.failed: list[str] = []  # requests that failed, with the reason

    def send(self, method: str, params: dict | None = None) -> dict:
        return self.browser.send(method, params, session=self.session)

    def evaluate(self, expression: str):
        """The value of a JavaScript expression (Promises awaited), as JSON data."""
        reply = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True, "awaitPromise": True})
        if "exceptionDetails" in reply:
            raise BrowserError(f"{expression[:60]}...: {reply['exceptionDetails']}")
        return reply["result"].get("value")

    def screenshot(self, path: str) -> None:
        """A PNG of the whole page: the viewport's width (scroll bar included), the page's height."""
        height = self.send("Page.getLayoutMetrics")["cssContentSize"]["height"]
        reply = self.send(
            "Page.captureScreenshot",
            {
                "format": "png",
                "captureBeyondViewport": True,
                "clip": {"x": 0, "y": 0, "width": self.width, "height": height, "scale": 1},
            },
        )
        with open(path, "wb") as fh:
            fh.write(base64.b64decode(reply["data"]))


class Chromium:
    """One headless Chromium process; ``open(url, width=..., height=..., mobile=...)`` loads a page."""

    def __init__(self, executable: str, *, timeout_s: float = 60.0):
        self.timeout_s = timeout_s
        self._profile = tempfile.mkdtemp(prefix="sss_lab_chromium_")
        to_child_r, self._to_child = os.pipe()
        self._from_child, from_child_w = os.pipe()

        def child_fds():  # runs in the child before exec: the protocol wants fds 3 and 4
            high_r = fcntl.fcntl(to_child_r, fcntl.F_DUPFD, 10)
            high_w = fcntl.fcntl(from_child_w, fcntl.F_DUPFD, 10)
            os.dup2(high_r, 3)
            os.dup2(high_w, 4)

        self._log = open(os.path.join(self._profile, "chromium.log"), "wb")  # noqa: SIM115 (closed in close())
        self.proc = subprocess.Popen(
            [executable, *FLAGS, f"--user-data-dir={self._profile}", "about:blank"],
            stdin=subprocess.DEVNULL,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            preexec_fn=child_fds,
            pass_fds=(3, 4),
        )
        os.close(to_child_r)
        os.close(from_child_w)
        self._next_id = 0
        self._replies: dict[int, dict] = {}
        self._events: queue.Queue = queue.Queue()
        self._lock = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    # -- protocol ---------------------------------------------------------------------------
    def _read(self) -> None:
        buffer = b""
        while True:
            try:
                chunk = os.read(self._from_child, 1 << 16)
            except OSError:
                chunk = b""
            if not chunk:
                with self._lock:
                    self._replies[-1] = {"error": {"message": "Chromium closed the pipe"}}
                    self._lock.notify_all()
                return
            buffer += chunk
            while b"\0" in buffer:
                raw, buffer = buffer.split(b"\0", 1)
                message = json.loads(raw)
                if "id" in message:
                    with self._lock:
                        self._replies[message["id"]] = message
                        self._lock.notify_all()
                else:
                    self._events.put(message)

    def send(self, method: str, params: dict | None = None, *, session: str | None = None) -> dict:
        with self._lock:
            self._next_id += 1
            ident = self._next_id
        message = {"id": ident, "method": method, "params": params or {}}
        if session is not None:
            message["sessionId"] = session
        os.write(self._to_child, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + self.timeout_s
        with self._lock:
            while ident not in self._replies:
                if -1 in self._replies:
                    raise BrowserError(f"{method}: {self._replies[-1]['error']['message']} ({self.log_tail()})")
                left = deadline - time.monotonic()
                if left <= 0:
                    raise BrowserError(f"{method}: no answer from Chromium in {self.timeout_s:.0f} s")
                self._lock.wait(left)
            reply = self._replies.pop(ident)
        if "error" in reply:
            raise BrowserError(f"{method}: {reply['error']}")
        return reply.get("result", {})

    def log_tail(self) -> str:
        self._log.flush()
        with open(self._log.name, "rb") as fh:
            return fh.read()[-2000:].decode(errors="replace")

    # -- pages ------------------------------------------------------------------------------
    def open(self, url: str, *, width: int, height: int, mobile: bool = False, scale: float = 1.0) -> Page:
        """Load ``url`` in a new tab with a ``width`` x ``height`` CSS-pixel viewport and wait for
        its load event (every picture loaded or failed). ``mobile`` emulates a phone: the page's
        viewport meta tag decides its layout width, as on a real phone."""
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        page = Page(self, session, width)
        for domain in ("Page", "Runtime", "Log", "Network"):
            page.send(f"{domain}.enable")
        page.send(
            "Emulation.setDeviceMetricsOverride",
            {"width": width, "height": height, "deviceScaleFactor": scale, "mobile": mobile},
        )
        self._drain(page)
        page.send("Page.navigate", {"url": url})
        deadline = time.monotonic() + self.timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise BrowserError(f"{url}: no load event in {self.timeout_s:.0f} s")
            try:
                event = self._events.get(timeout=left)
            except queue.Empty:
                continue
            if self._record(page, event) == "load":
                break
        # Messages logged during the load may arrive just after the load event.
        time.sleep(0.2)
        self._drain(page)
        return page

    def _drain(self, page: Page) -> None:
        while True:
            try:
                self._record(page, self._events.get_nowait())
            except queue.Empty:
                return

    @staticmethod
    def _record(page: Page, event: dict) -> str | None:
        if event.get("sessionId") != page.session:
            return None
        method, params = event.get("method"), event.get("params", {})
        if method == "Page.loadEventFired":
            return "load"
        if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "warning", "assert"):
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", []))
            page.console.append(f"console.{params['type']}: {text}")
        elif method == "Runtime.exceptionThrown":
            details = params.get("exceptionDetails", {})
            page.console.append(f"exception: {details.get('exception', {}).get('description', details.get('text'))}")
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") in ("error", "warning"):
            entry = params["entry"]
            page.console.append(f"{entry['level']}: {entry.get('text')} {entry.get('url', '')}".strip())
        elif method == "Network.loadingFailed":
            page.failed.append(f"{params.get('errorText')} (request {params.get('requestId')})")
        return None

    def close(self) -> None:
        try:
            self.send("Browser.close")
        except BrowserError:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        for fd in (self._to_child, self._from_child):
            try:
                os.close(fd)
            except OSError:
                pass
        self._log.close()
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


# -- the comparison report ----------------------------------------------------------------------

#: Viewports the report must read well at, in CSS pixels: a phone (emulated as one, so the page's
#: viewport tag applies) and a desktop window.
VIEWPORTS = {
    "phone": {"width": 390, "height": 844, "mobile": True, "scale": 2.0},
    "desktop": {"width": 1280, "height": 900, "mobile": False, "scale": 1.0},
}

_REPORT_PROBE = """(() => {
  const box = (el) => { const r = el.getBoundingClientRect(); return {width: r.width, height: r.height}; };
  const images = Array.from(document.images).map((img) => ({
    src: img.getAttribute("src"), loaded: img.complete && img.naturalWidth > 0, ...box(img)}));
  const svgs = Array.from(document.querySelectorAll("svg")).map((svg) => ({
    ...box(svg),
    circles: svg.querySelectorAll("circle").length,
    texts: Array.from(svg.querySelectorAll("text")).map((t) => t.textContent),
    smallest_text_px: Math.min(...Array.from(svg.querySelectorAll("text")).map((t) => box(t).height)),
    texts_outside: Array.from(svg.querySelectorAll("text")).filter((t) => {
      const b = t.getBoundingClientRect(), v = svg.getBoundingClientRect();  // as drawn, rotation included
      return b.left < v.left - 0.5 || b.top < v.top - 0.5 || b.right > v.right + 0.5 || b.bottom > v.bottom + 0.5;
    }).map((t) => t.textContent),
  }));
  const texts = Array.from(document.querySelectorAll("p, li, td, th, h1, h2"));
  return {
    inner_width: window.innerWidth,
    page_width: document.documentElement.scrollWidth,
    images, svgs,
    smallest_font_px: Math.min(...texts.map((el) => parseFloat(getComputedStyle(el).fontSize))),
    text: document.body.innerText,
    // What the first screen shows, before any scrolling.
    first_screen: texts.filter((el) => el.getBoundingClientRect().top < window.innerHeight)
      .map((el) => el.innerText).join(" | "),
  };
})()"""


def inspect_report(browser: Chromium, folder: str, screenshots: str | None = None) -> dict:
    """Open ``folder``/report.html at each of ``VIEWPORTS``; per viewport: the probe's numbers
    (images and whether each loaded, the inline SVGs, page and viewport width, smallest font),
    the console errors and failed requests, and the screenshot's path (when ``screenshots``)."""
    url = "file://" + os.path.abspath(os.path.join(folder, "report.html"))
    out = {}
    for name, viewport in VIEWPORTS.items():
        page = browser.open(url, **viewport)
        info = page.evaluate(_REPORT_PROBE)
        info["console"], info["failed"] = page.console, page.failed
        if screenshots:
            os.makedirs(screenshots, exist_ok=True)
            info["screenshot"] = os.path.join(screenshots, f"report_{name}.png")
            page.screenshot(info["screenshot"])
        page.send("Page.close")
        out[name] = info
    for plot in PLOTS:
        svg = browser.open("file://" + os.path.abspath(os.path.join(folder, plot)), width=800, height=600)
        out[plot] = {
            "root": svg.evaluate("document.documentElement.localName"),
            "parse_errors": svg.evaluate("document.getElementsByTagName('parsererror').length"),
            "circles": svg.evaluate("document.querySelectorAll('circle').length"),
            "console": svg.console,
            "failed": svg.failed,
        }
        svg.send("Page.close")
    return out


#: The report's plots, in the order the page shows them inline.
PLOTS = ("pareto.svg", "pareto_samples.svg")


def _plotted(data: dict, plot: str) -> list[dict]:
    """The entries a plot must draw: measured ones with a time (the seconds plot) or with samples
    per pixel (the samples plot)."""
    measured = [e for e in data["entries"] if e["metrics"].get("rel_rmse") is not None]
    if plot == "pareto.svg":
        return [e for e in measured if e["time_s"].get("total")]
    return [e for e in measured if e.get("samples_per_pixel")]


#: Readable sizes, in CSS pixels: text at least 14 px (browsers default to 16 px), and the plot's
#: labels at least 10 px tall as drawn (on a phone the plot scrolls sideways rather than shrinking).
MIN_FONT_PX = 14
MIN_PLOT_TEXT_PX = 10


def report_problems(folder: str, seen: dict) -> list[str]:
    """What is wrong with the report page, judged against the report's own ``metrics.json``:
    every picture it names must load, the plot must draw one dot per measured entry with every
    label inside it, nothing may log an error or fail to load, and at every viewport the page
    must be laid out at the device's width without sideways scrolling, with readable text."""
    with open(os.path.join(folder, "metrics.json"), encoding="utf-8") as fh:
        data = json.load(fh)
    wanted = {data["grid"]["file"], data["reference_image"]}
    if data.get("summary"):
        wanted.add(data["summary"]["file"])
    for e in data["entries"]:
        wanted |= {e[k] for k in ("image", "error_image") if e.get(k)}
    problems = []
    for name, viewport in VIEWPORTS.items():
        page = seen[name]
        problems += [f"{name}: console: {line}" for line in page["console"]]
        problems += [f"{name}: request failed: {line}" for line in page["failed"]]
        srcs = {img["src"] for img in page["images"]}
        if srcs != wanted:
            problems.append(f"{name}: pictures shown {sorted(srcs)}, expected {sorted(wanted)}")
        problems += [f"{name}: picture did not load: {i['src']}" for i in page["images"] if not i["loaded"]]
        if len(page["svgs"]) != len(PLOTS):
            problems.append(f"{name}: {len(page['svgs'])} inline SVG plots, expected {len(PLOTS)}")
        for plot, svg in zip(PLOTS, page["svgs"], strict=False):
            plotted = _plotted(data, plot)
            if svg["width"] < 300 or svg["height"] < 150:
                problems.append(f"{name}: plot drawn {svg['width']:.0f}x{svg['height']:.0f} px")
            if svg["circles"] != len(plotted):
                problems.append(f"{name}: {plot} has {svg['circles']} dots for {len(plotted)} measured entries")
            missing = {e["name"] for e in plotted} - set(svg["texts"])
            if missing:
                problems.append(f"{name}: {plot} does not name {sorted(missing)}")
            if svg["smallest_text_px"] < MIN_PLOT_TEXT_PX:
                problems.append(f"{name}: {plot} text {svg['smallest_text_px']:.1f} px tall (< {MIN_PLOT_TEXT_PX})")
            problems += [f"{name}: {plot} label cut off at the edge: {t}" for t in svg["texts_outside"]]
        if page["inner_width"] != viewport["width"]:
            problems.append(f"{name}: laid out {page['inner_width']} px wide on a {viewport['width']} px screen")
        if page["page_width"] > page["inner_width"]:
            problems.append(f"{name}: the page scrolls sideways ({page['page_width']} > {page['inner_width']} px)")
        if page["smallest_font_px"] < MIN_FONT_PX:
            problems.append(f"{name}: text of {page['smallest_font_px']} px (< {MIN_FONT_PX})")
    for plot in PLOTS:
        alone, plotted = seen[plot], _plotted(data, plot)
        if alone["root"] != "svg" or alone["parse_errors"]:
            problems.append(f"{plot} does not parse as SVG: {alone}")
        if alone["circles"] != len(plotted) or alone["console"] or alone["failed"]:
            problems.append(f"{plot}: {alone['circles']} dots, console {alone['console']}, failed {alone['failed']}")
    return problems
