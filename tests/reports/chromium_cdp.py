"""Open a page in headless Chromium over the DevTools protocol (stdlib only) and return
its console errors and a screenshot.

Chromium is started with ``--remote-debugging-pipe``: it reads NUL-terminated JSON
commands on fd 3 and writes replies and events on fd 4 (a ``sh`` wrapper maps the child's
stdin/stdout onto them). Errors collected: uncaught exceptions, ``console.error`` /
``console.assert``, and every browser log entry of level error (failed resource loads,
blocked network requests). Host names resolve nowhere (``--host-resolver-rules``), so
any network reference shows up as an error.
"""
from __future__ import annotations

import base64
import json
import os
import select
import shutil
import subprocess
import tempfile
import time

__all__ = ["chromium_path", "open_page", "FLAGS", "OVERFLOW_JS"]

#: the page's width, its scroll width, and the elements reaching past the viewport's right edge
OVERFLOW_JS = """(() => {
  const width = document.documentElement.clientWidth, bad = [];
  for (const el of document.querySelectorAll('body *')) {
    const r = el.getBoundingClientRect();
    if (r.width > 0 && r.right > width + 1) bad.push(el.tagName + (el.id ? '#' + el.id : '') + ' right=' + Math.round(r.right));
  }
  return JSON.stringify({width: width, scroll: document.documentElement.scrollWidth, bad: bad.slice(0, 12)});
})()"""

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--host-resolver-rules=MAP * ~NOTFOUND", "--remote-debugging-pipe")


def chromium_path() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


class _Pipe:
    def __init__(self, proc):
        self.proc, self.buf, self.next_id, self.events = proc, b"", 0, []

    def send(self, method, params=None, session=None) -> int:
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        self.proc.stdin.write(json.dumps(msg).encode() + b"\0")
        self.proc.stdin.flush()
        return self.next_id

    def read(self, deadline: float) -> dict:
        while b"\0" not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.proc.stdout], [], [], left)[0]:
                raise TimeoutError("no reply from Chromium")
            chunk = os.read(self.proc.stdout.fileno(), 1 << 16)
            if not chunk:
                raise RuntimeError("Chromium closed the DevTools pipe")
            self.buf += chunk
        raw, self.buf = self.buf.split(b"\0", 1)
        return json.loads(raw)

    def call(self, method, params=None, session=None, timeout_s=30.0) -> dict:
        want, deadline = self.send(method, params, session), time.monotonic() + timeout_s
        while True:
            msg = self.read(deadline)
            if msg.get("id") == want:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self.events.append(msg)

    def wait_event(self, name, timeout_s=30.0) -> dict:
        deadline = time.monotonic() + timeout_s
        for i, msg in enumerate(self.events):
            if msg.get("method") == name:
                return self.events.pop(i)
        while True:
            msg = self.read(deadline)
            if msg.get("method") == name:
                return msg
            self.events.append(msg)


def _errors(events) -> list[str]:
    found = []
    for msg in events:
        m, p = msg.get("method"), msg.get("params", {})
        if m == "Runtime.exceptionThrown":
            found.append("exception: " + p["exceptionDetails"].get("text", "") + " " +
                         str(p["exceptionDetails"].get("exception", {}).get("description", "")))
        elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            found.append("console.error: " + " ".join(str(a.get("value", a.get("description", "")))
                                                      for a in p.get("args", [])))
        elif m == "Log.entryAdded" and p["entry"].get("level") == "error":
            found.append(f"log: {p['entry'].get('text')} {p['entry'].get('url', '')}")
    return found


def open_page(url: str, *, width: int = 1200, max_height: int = 6000, timeout_s: float = 60.0,
              evaluate: str | None = None, widths: tuple[int, ...] = ()):
    """Load ``url`` in a viewport ``width`` CSS pixels wide; returns (errors list[str],
    screenshot PNG bytes of the page's top part), plus the value of the JavaScript
    expression ``evaluate`` (a string) when one is given — a dict {width: value} over
    ``widths`` (the viewport resized in turn, one browser) when those are given."""
    exe = chromium_path()
    with tempfile.TemporaryDirectory(prefix="feeler-chromium-") as profile:
        cmd = ["sh", "-c", 'exec "$0" "$@" 3<&0 4>&1 </dev/null >/dev/null', exe, *FLAGS,
               f"--user-data-dir={profile}", f"--window-size={width},900", "about:blank"]
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL)
        try:
            pipe = _Pipe(proc)
            target = pipe.call("Target.createTarget", {"url": "about:blank"}, timeout_s=timeout_s)["targetId"]
            sid = pipe.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
            for domain in ("Runtime", "Log", "Page"):
                pipe.call(f"{domain}.enable", session=sid)
            pipe.call("Emulation.setDeviceMetricsOverride", {"width": width, "height": 900, "deviceScaleFactor": 1,
                                                             "mobile": False}, session=sid)
            pipe.call("Page.navigate", {"url": url}, session=sid)
            pipe.wait_event("Page.loadEventFired", timeout_s)
            pipe.call("Runtime.evaluate", {"expression": "1"}, session=sid)   # flush pending events
            size = pipe.call("Page.getLayoutMetrics", session=sid)["cssContentSize"]
            clip = {"x": 0, "y": 0, "width": width, "height": min(size["height"], max_height), "scale": 0.5}
            shot = pipe.call("Page.captureScreenshot", {"format": "png", "clip": clip,
                                                        "captureBeyondViewport": True}, session=sid)
            value = None
            if evaluate is not None:
                value = {}
                for w in widths or (width,):
                    pipe.call("Emulation.setDeviceMetricsOverride", {"width": w, "height": 900, "deviceScaleFactor": 1,
                                                                     "mobile": False}, session=sid)
                    value[w] = pipe.call("Runtime.evaluate", {"expression": evaluate, "returnByValue": True},
                                         session=sid)["result"].get("value")
                value = value if widths else value[width]
            errors = _errors(pipe.events)
            try:
                pipe.call("Browser.close", timeout_s=5)
            except (RuntimeError, TimeoutError):
                pass
            png = base64.b64decode(shot["data"])
            return (errors, png) if evaluate is None else (errors, png, value)
        finally:
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
