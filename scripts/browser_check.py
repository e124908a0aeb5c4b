#!/usr/bin/env python3
"""Loads an HTML file in headless Chromium over the DevTools protocol and reports what a reader
would see: console messages and errors (including resources that failed to load), the laid-out
size of every <svg> and <img> (and whether each image decoded), and a PNG screenshot.

Usage: browser_check.py CHROMIUM PAGE.html SCREENSHOT.png [WIDTH HEIGHT]
Prints one JSON object to stdout: {"console": [...], "elements": [...], "title": ...}.
Exits 2 when Chromium cannot be started or does not answer. Standard library only: the protocol
runs over --remote-debugging-pipe (file descriptors 3 and 4, NUL-separated JSON).
"""

import base64
import json
import os
import pathlib
import select
import subprocess
import sys
import tempfile
import time

TIMEOUT_S = 120.0

MEASURE = """JSON.stringify(Array.from(document.querySelectorAll('svg, img')).map(e => {
  const r = e.getBoundingClientRect();
  return {tag: e.tagName.toLowerCase(), width: r.width, height: r.height,
          decoded: e.tagName.toLowerCase() !== 'img' || (e.complete && e.naturalWidth > 0)};
}))"""


class Browser:
    def __init__(self, chromium, profile):
        # Chromium's own log goes to a file: a pipe nobody reads could fill and stall it.
        self.log = open(os.path.join(profile, "chromium.log"), "w+b")
        to_browser_r, self.to_browser = os.pipe()
        self.from_browser, from_browser_w = os.pipe()
        # Chromium reads commands on fd 3 and writes answers on fd 4; the shell puts the pipes
        # there (file descriptors passed to a child keep their numbers).
        self.proc = subprocess.Popen(
            ["sh", "-c", f'exec "$0" "$@" 3<&{to_browser_r} 4>&{from_browser_w}', chromium,
             "--headless", "--no-sandbox", "--disable-gpu",
             "--disable-dev-shm-usage", "--no-first-run", "--no-default-browser-check",
             "--hide-scrollbars", "--remote-debugging-pipe",
             f"--user-data-dir={profile}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=self.log,
            pass_fds=(to_browser_r, from_browser_w),
        )
        os.close(to_browser_r)
        os.close(from_browser_w)
        self.buffer = b""
        self.next_id = 0
        self.events = []

    def send(self, method, params=None, session=None):
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self.to_browser, json.dumps(message).encode() + b"\0")
        return self.wait(lambda m: m.get("id") == self.next_id)

    def wait(self, done):
        deadline = time.monotonic() + TIMEOUT_S
        while True:
            while b"\0" in self.buffer:
                raw, self.buffer = self.buffer.split(b"\0", 1)
                message = json.loads(raw)
                if "method" in message:
                    self.events.append(message)
                if done(message):
                    if "error" in message:
                        raise RuntimeError(f"DevTools error: {message['error']}")
                    return message
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("Chromium did not answer in time")
            ready, _, _ = select.select([self.from_browser], [], [], left)
            if ready:
                chunk = os.read(self.from_browser, 1 << 20)
                if not chunk:
                    raise RuntimeError("Chromium closed the DevTools pipe")
                self.buffer += chunk

    def close(self):
        try:
            self.send("Browser.close")
        except Exception:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def main():
    if len(sys.argv) not in (4, 6):
        print(__doc__, file=sys.stderr)
        return 2
    chromium, page, screenshot = sys.argv[1:4]
    width, height = (int(sys.argv[4]), int(sys.argv[5])) if len(sys.argv) == 6 else (1280, 2000)
    url = pathlib.Path(page).resolve().as_uri()
    with tempfile.TemporaryDirectory(prefix="twincell-chromium-") as profile:
        try:
            browser = Browser(chromium, profile)
        except OSError as e:
            print(f"browser_check: cannot start {chromium}: {e}", file=sys.stderr)
            return 2
        try:
            targets = browser.send("Target.getTargets")["result"]["targetInfos"]
            page_target = next(t["targetId"] for t in targets if t["type"] == "page")
            session = browser.send("Target.attachToTarget",
                                   {"targetId": page_target, "flatten": True})["result"]["sessionId"]
            for domain in ("Page.enable", "Runtime.enable", "Log.enable"):
                browser.send(domain, session=session)
            browser.send("Emulation.setDeviceMetricsOverride",
                         {"width": width, "height": height, "deviceScaleFactor": 1,
                          "mobile": False}, session=session)
            browser.events.clear()
            browser.send("Page.navigate", {"url": url}, session=session)
            if not any(e.get("method") == "Page.loadEventFired" for e in browser.events):
                browser.wait(lambda m: m.get("method") == "Page.loadEventFired")
            # Let late console messages and layout settle.
            browser.send("Runtime.evaluate",
                         {"expression": "new Promise(r => requestAnimationFrame(() => setTimeout(r, 200)))",
                          "awaitPromise": True}, session=session)
            measured = browser.send("Runtime.evaluate",
                                    {"expression": MEASURE, "returnByValue": True},
                                    session=session)["result"]["result"]["value"]
            title = browser.send("Runtime.evaluate",
                                 {"expression": "document.title", "returnByValue": True},
                                 session=session)["result"]["result"]["value"]
            shot = browser.send("Page.captureScreenshot", {"format": "png"}, session=session)
            pathlib.Path(screenshot).write_bytes(base64.b64decode(shot["result"]["data"]))
        except (RuntimeError, TimeoutError, StopIteration, KeyError) as e:
            browser.proc.kill()
            browser.proc.wait()
            browser.log.seek(0)
            log = browser.log.read().decode(errors="replace")[-2000:]
            print(f"browser_check: {type(e).__name__}: {e}\n{log}", file=sys.stderr)
            return 2
        console = []
        for event in browser.events:
            method, params = event.get("method"), event.get("params", {})
            if method == "Runtime.consoleAPICalled":
                text = " ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", []))
                console.append({"level": params.get("type"), "text": text})
            elif method == "Runtime.exceptionThrown":
                details = params.get("exceptionDetails", {})
                console.append({"level": "error",
                                "text": details.get("exception", {}).get("description", details.get("text", ""))})
            elif method == "Log.entryAdded":
                entry = params.get("entry", {})
                console.append({"level": entry.get("level"), "text": entry.get("text", "")})
        browser.close()
    json.dump({"title": title, "console": console, "elements": json.loads(measured)}, sys.stdout)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
