"""Load a kisscal report in headless Chromium, fail on any console error, take screenshots.

Run as ``python -m tests.report.browser_check REPORT.html OUT.png [--full]``: writes
OUT.png (the first screen, 1280 x 900) and OUT-viewer.png (the 3D viewer after a drag,
a zoom and a few played frames); with ``--full``, also OUT-full.png (the whole page).
Exit status 1 on a console error, an uncaught exception, a request that leaves the file
(the report must be offline), or a viewer that drew nothing.

Not a pytest test: CI has no Chromium (``apt-get install chromium`` here). It talks to
the browser over the DevTools protocol on a pipe (``--remote-debugging-pipe``), with the
standard library only.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import select
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--remote-debugging-pipe",
    "--hide-scrollbars",
]
WIDTH, HEIGHT = 1280, 900


class Browser:
    """A Chromium process driven over the DevTools pipe (fd 3 in, fd 4 out)."""

    def __init__(self, chromium: str, profile: str) -> None:
        to_chrome_r, self._to_chrome = os.pipe()
        self._from_chrome, from_chrome_w = os.pipe()
        script = f'exec "$0" "$@" 3<&{to_chrome_r} 4>&{from_chrome_w}'
        self.proc = subprocess.Popen(
            ["bash", "-c", script, chromium, *FLAGS, f"--user-data-dir={profile}"],
            pass_fds=(to_chrome_r, from_chrome_w),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._buffer = b""
        self._next = 0
        self.events: list[dict[str, Any]] = []
        self.session: str | None = None

    def send(self, method: str, params: dict[str, Any] | None = None, timeout: float = 30) -> Any:
        self._next += 1
        msg: dict[str, Any] = {"id": self._next, "method": method, "params": params or {}}
        if self.session and not method.startswith("Target."):
            msg["sessionId"] = self.session
        os.write(self._to_chrome, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            reply = self._read(deadline)
            if reply.get("id") == self._next:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_event(self, name: str, timeout: float = 30) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        for e in self.events:
            if e.get("method") == name:
                return e
        while True:
            e = self._read(deadline)
            self.events.append(e)
            if e.get("method") == name:
                return e

    def pump(self, seconds: float) -> None:
        """Collect the events that arrive within ``seconds``."""
        deadline = time.monotonic() + seconds
        try:
            while True:
                self.events.append(self._read(deadline))
        except TimeoutError:
            return

    def _read(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._from_chrome], [], [], left)[0]:
                raise TimeoutError("no answer from Chromium")
            chunk = os.read(self._from_chrome, 1 << 20)
            if not chunk:
                raise RuntimeError("Chromium closed the DevTools pipe")
            self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(message)

    def close(self) -> None:
        try:
            self.send("Browser.close", timeout=5)
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def problems(events: list[dict[str, Any]]) -> list[str]:
    """Console errors, uncaught exceptions and requests that leave the file."""
    found = []
    for e in events:
        method, p = e.get("method"), e.get("params", {})
        if method == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            text = d.get("exception", {}).get("description") or d.get("text")
            found.append(f"exception: {text}")
        elif method == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            args = " ".join(str(a.get("value", a.get("description", ""))) for a in p["args"])
            found.append(f"console.{p['type']}: {args}")
        elif method == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
            found.append(f"log: {p['entry'].get('text')} {p['entry'].get('url', '')}")
        elif method == "Network.requestWillBeSent":
            url = p.get("request", {}).get("url", "")
            if not url.startswith(("file:", "data:", "about:")):
                found.append(f"network request (report must be offline): {url[:120]}")
    return found


def screenshot(b: Browser, path: Path, clip: dict[str, float] | None = None) -> None:
    params: dict[str, Any] = {"format": "png"}
    if clip:
        params["clip"] = {**clip, "scale": 1}
        params["captureBeyondViewport"] = True
    data = b.send("Page.captureScreenshot", params)["data"]
    path.write_bytes(base64.b64decode(data))


def evaluate(b: Browser, expression: str) -> Any:
    result = b.send("Runtime.evaluate", {"expression": expression, "returnByValue": True})
    if "exceptionDetails" in result:
        raise RuntimeError(f"{expression[:60]}: {result['exceptionDetails'].get('text')}")
    return result["result"].get("value")


def drag(b: Browser, x: float, y: float, dx: float, dy: float) -> None:
    mouse = "Input.dispatchMouseEvent"
    b.send(mouse, {"type": "mousePressed", "x": x, "y": y, "button": "left", "clickCount": 1})
    for k in range(1, 6):
        b.send(
            mouse,
            {
                "type": "mouseMoved",
                "x": x + dx * k / 5,
                "y": y + dy * k / 5,
                "button": "left",
                "buttons": 1,
            },
        )
    b.send(mouse, {"type": "mouseReleased", "x": x + dx, "y": y + dy, "button": "left"})
    b.send(mouse, {"type": "mouseWheel", "x": x, "y": y, "deltaX": 0, "deltaY": -240})


def check(report: Path, out: Path, full: bool = False) -> list[str]:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("chromium not found: apt-get install -y chromium")
    with tempfile.TemporaryDirectory(prefix="kisscal-chromium-") as profile:
        b = Browser(chromium, profile)
        try:
            target = b.send("Target.createTarget", {"url": "about:blank"})["targetId"]
            b.session = b.send("Target.attachToTarget", {"targetId": target, "flatten": True})[
                "sessionId"
            ]
            for domain in ("Page", "Runtime", "Log", "Network"):
                b.send(f"{domain}.enable")
            b.send(
                "Emulation.setDeviceMetricsOverride",
                {"width": WIDTH, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False},
            )
            b.send("Page.navigate", {"url": report.resolve().as_uri()})
            b.wait_event("Page.loadEventFired", 60)
            b.pump(1.0)
            screenshot(b, out)
            found = _viewer(b, out.with_name(out.stem + "-viewer.png"))
            if full:
                evaluate(b, "document.querySelectorAll('details').forEach(d => d.open = true)")
                height = evaluate(b, "document.documentElement.scrollHeight")
                evaluate(b, "window.scrollTo(0, 0)")
                clip = {"x": 0, "y": 0, "width": WIDTH, "height": float(height)}
                screenshot(b, out.with_name(out.stem + "-full.png"), clip)
            b.pump(0.5)
            return found + problems(b.events)
        finally:
            b.close()


def _viewer(b: Browser, path: Path) -> list[str]:
    """Scroll to the viewer, turn, zoom and play it; screenshot it; check it drew."""
    if not evaluate(b, "!!document.getElementById('kc-viewer')"):
        return ["no 3D viewer in the report"]
    evaluate(b, "document.getElementById('kc-viewer').scrollIntoView()")
    rect = evaluate(
        b,
        "(() => {const r = document.getElementById('kc-canvas').getBoundingClientRect();"
        "return [r.x, r.y, r.width, r.height];})()",
    )
    # every trial once, every view button, the last frame: the script must take them all
    evaluate(
        b,
        "(() => {const s = document.getElementById('kc-trial'), f = document.getElementById("
        "'kc-frame'); for (let k = s.options.length - 1; k >= 0; k--) { s.value = k;"
        " s.dispatchEvent(new Event('change')); f.value = f.max;"
        " f.dispatchEvent(new Event('input')); document.querySelectorAll('#kc-viewer "
        "[data-view]').forEach(v => v.click()); }})()",
    )
    drag(b, rect[0] + rect[2] / 2, rect[1] + rect[3] / 2, 60, 20)
    evaluate(b, "document.getElementById('kc-play').click()")
    b.pump(1.0)
    evaluate(b, "document.getElementById('kc-play').click()")
    inked = evaluate(
        b,
        "(() => {const c = document.getElementById('kc-canvas');"
        "const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
        "let n = 0; for (let i = 3; i < d.length; i += 4) { if (d[i] > 0) n++; } return n;})()",
    )
    box = evaluate(
        b,
        "(() => {const r = document.getElementById('kc-viewer').getBoundingClientRect();"
        "return [r.x + window.scrollX, r.y + window.scrollY, r.width, r.height];})()",
    )
    screenshot(b, path, {"x": box[0], "y": box[1], "width": box[2], "height": box[3]})
    readout = evaluate(b, "document.getElementById('kc-time').textContent")
    print(f"viewer: {inked} drawn pixels, {readout}")
    return [] if inked > 1000 else ["the 3D viewer drew nothing"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--full", action="store_true", help="also a full-page screenshot")
    args = parser.parse_args(argv)
    if not args.report.is_file():
        print(f"{args.report}: not found", file=sys.stderr)
        return 2
    found = check(args.report, args.out, args.full)
    size = args.report.stat().st_size
    print(f"report: {args.report} ({size / 1e6:.2f} MB)")
    kinds = ("", "-viewer", "-full") if args.full else ("", "-viewer")
    shots = [args.out.with_name(args.out.stem + k + ".png") for k in kinds]
    print("screenshots: " + ", ".join(str(p) for p in shots if p.is_file()))
    for line in found:
        print(f"PROBLEM {line}")
    print("browser check: " + ("failed" if found else "passed, no console error"))
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
