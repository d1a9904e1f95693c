#!/usr/bin/env python3
"""Opens a report (or any local HTML page) in headless Chromium, takes a screenshot, and fails on
console errors or a page without its tables and figures.

Usage: check_report.py PAGE.html [--screenshot OUT.png] [--min-tables N] [--min-figures N]
                       [--width PX] [--max-height PX] [--chromium PATH]

Chromium runs headless with a new, empty profile, no sandbox (it may run as root in CI), no GPU and
no network services; it is driven over the DevTools protocol (python3-websocket). Checked:
  - no console message of level error, no uncaught exception, no failed resource load (Log and
    Runtime domains), no request leaving the machine (http/https/ws: the page must be
    self-contained);
  - at least --min-tables <table> elements and --min-figures <img> elements, every image decoded
    (naturalWidth > 0), the failure matrix present (#failure-matrix) when --report is given.
The screenshot is the whole page at --width CSS pixels (cut at --max-height).
Exit 0: fine; 1: problems (listed); 2: usage; 3: Chromium or python3-websocket missing (the message
names the Debian packages: chromium python3-websocket).
"""
import argparse
import base64
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import atomic_save  # noqa: E402

try:
    import websocket  # python3-websocket
except ImportError:
    websocket = None


def find_chromium(explicit):
    for c in ([explicit] if explicit else []) + ["chromium", "chromium-browser", "google-chrome",
                                                 "google-chrome-stable"]:
        path = shutil.which(c) if c else None
        if path:
            return path
    return None


class DevTools:
    def __init__(self, ws_url):
        self.ws = websocket.create_connection(ws_url, timeout=60, suppress_origin=True)
        self.next_id = 0
        self.events = []

    def call(self, method, **params):
        self.next_id += 1
        my_id = self.next_id
        self.ws.settimeout(60)
        self.ws.send(json.dumps({"id": my_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == my_id:
                if "error" in msg:
                    raise RuntimeError("%s: %s" % (method, msg["error"]))
                return msg.get("result", {})
            if "method" in msg:
                self.events.append(msg)

    def wait_for(self, method, timeout):
        deadline = time.monotonic() + timeout
        for e in self.events:
            if e["method"] == method:
                return True
        while time.monotonic() < deadline:
            self.ws.settimeout(max(0.1, deadline - time.monotonic()))
            try:
                msg = json.loads(self.ws.recv())
            except websocket.WebSocketTimeoutException:
                break
            if "method" in msg:
                self.events.append(msg)
                if msg["method"] == method:
                    return True
        return False

    def drain(self, seconds):
        """Collects events for a little while (late console messages)."""
        self.wait_for("__never__", seconds)

    def close(self):
        self.ws.close()


def console_problems(events):
    problems = []
    for e in events:
        m, p = e["method"], e.get("params", {})
        if m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", []))
            problems.append("console.%s: %s" % (p["type"], text))
        elif m == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            problems.append("uncaught exception: %s %s" % (
                d.get("text", ""), d.get("exception", {}).get("description", "")))
        elif m == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
            entry = p["entry"]
            problems.append("console error (%s): %s %s" % (entry.get("source"), entry.get("text"),
                                                          entry.get("url", "")))
        elif m == "Network.loadingFailed":
            problems.append("resource failed to load: %s" % p.get("errorText"))
        elif m == "Network.requestWillBeSent":
            url = p.get("request", {}).get("url", "")
            if url.split(":", 1)[0] in ("http", "https", "ws", "wss"):
                problems.append("network request (page not self-contained): %s" % url)
    return problems


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("page")
    parser.add_argument("--screenshot", default="")
    parser.add_argument("--min-tables", type=int, default=1)
    parser.add_argument("--min-figures", type=int, default=1)
    parser.add_argument("--report", action="store_true",
                        help="also require the report's sections (#failure-matrix, #tables, ...)")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--max-height", type=int, default=16000)
    parser.add_argument("--chromium", default=os.environ.get("MARGLAB_CHROMIUM", ""))
    parser.add_argument("--timeout", type=float, default=60)
    args = parser.parse_args()

    chromium = find_chromium(args.chromium)
    if chromium is None or websocket is None:
        missing = ([] if chromium else ["chromium"]) + ([] if websocket else ["python3-websocket"])
        print("check_report.py: %s not found; install the Debian packages: sudo apt-get install %s"
              % (" and ".join(missing), " ".join(missing)), file=sys.stderr)
        return 3
    if not os.path.isfile(args.page):
        print("check_report.py: %s: no such file" % args.page, file=sys.stderr)
        return 2

    profile = tempfile.mkdtemp(prefix="marglab-chromium-")
    log = open(os.path.join(profile, "chromium.log"), "w")
    proc = subprocess.Popen(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--no-default-browser-check", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--disable-extensions",
         "--disable-dev-shm-usage", "--hide-scrollbars", "--mute-audio",
         "--remote-debugging-address=127.0.0.1", "--remote-debugging-port=0",
         "--user-data-dir=" + profile, "--window-size=%d,900" % args.width, "about:blank"],
        stdout=log, stderr=subprocess.STDOUT)
    problems = []
    try:
        port_file = os.path.join(profile, "DevToolsActivePort")
        deadline = time.monotonic() + args.timeout
        while not (os.path.isfile(port_file) and open(port_file).read().strip()):
            if proc.poll() is not None or time.monotonic() > deadline:
                log.flush()
                print("check_report.py: Chromium did not start (see its output below)\n" +
                      open(os.path.join(profile, "chromium.log")).read()[-3000:],
                      file=sys.stderr)
                return 1
            time.sleep(0.1)
        port = int(open(port_file).read().split()[0])
        pages = []
        while not pages and time.monotonic() < deadline:
            with urllib.request.urlopen("http://127.0.0.1:%d/json/list" % port, timeout=10) as r:
                pages = [t for t in json.load(r) if t.get("type") == "page"]
            if not pages:
                time.sleep(0.1)
        if not pages:
            print("check_report.py: Chromium has no page target", file=sys.stderr)
            return 1
        dt = DevTools(pages[0]["webSocketDebuggerUrl"])
        for domain in ("Page", "Runtime", "Log", "Network"):
            dt.call(domain + ".enable")
        url = "file://" + os.path.abspath(args.page)
        nav = dt.call("Page.navigate", url=url)
        if nav.get("errorText"):
            problems.append("navigation failed: %s" % nav["errorText"])
        if not dt.wait_for("Page.loadEventFired", args.timeout):
            problems.append("the page did not finish loading within %.0f s" % args.timeout)
        dt.drain(0.5)

        probe = """(() => {
          const imgs = Array.from(document.images);
          return JSON.stringify({
            title: document.title,
            tables: document.querySelectorAll('table').length,
            images: imgs.length,
            broken: imgs.filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.alt || i.src.slice(0, 60)),
            sections: ['failure-matrix', 'tables', 'figures', 'notebooks', 'configuration']
                .filter(id => !document.getElementById(id)),
            height: Math.ceil(document.documentElement.scrollHeight),
            width: Math.ceil(document.documentElement.scrollWidth)});
        })()"""
        info = json.loads(dt.call("Runtime.evaluate", expression=probe,
                                  returnByValue=True)["result"]["value"])
        if info["tables"] < args.min_tables:
            problems.append("%d tables on the page, expected at least %d"
                            % (info["tables"], args.min_tables))
        if info["images"] < args.min_figures:
            problems.append("%d figures on the page, expected at least %d"
                            % (info["images"], args.min_figures))
        if info["broken"]:
            problems.append("figures that do not display: %s" % ", ".join(info["broken"]))
        if args.report and info["sections"]:
            problems.append("report sections missing: %s" % ", ".join(info["sections"]))

        if args.screenshot:
            height = min(info["height"], args.max_height)
            dt.call("Emulation.setDeviceMetricsOverride", width=args.width, height=height,
                    deviceScaleFactor=1, mobile=False)
            dt.drain(0.3)
            shot = dt.call("Page.captureScreenshot", format="png", captureBeyondViewport=True,
                           clip={"x": 0, "y": 0, "width": args.width, "height": height,
                                 "scale": 1})
            os.makedirs(os.path.dirname(os.path.abspath(args.screenshot)), exist_ok=True)
            atomic_save.write_bytes(args.screenshot, base64.b64decode(shot["data"]))
        problems = console_problems(dt.events) + problems
        dt.close()
        print("check_report.py: %s — %d tables, %d figures, page %dx%d px%s"
              % (args.page, info["tables"], info["images"], info["width"], info["height"],
                 ", screenshot " + args.screenshot if args.screenshot else ""))
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.close()
        shutil.rmtree(profile, ignore_errors=True)
    for p in problems:
        print("%s: %s" % (args.page, p), file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    atomic_save.unwind_on_stop_signals()  # Chromium is stopped and its profile removed
    atomic_save.run_main(main, "check_report.py")
