#!/usr/bin/env python3
"""Drives headless Chromium through its DevTools protocol (python3-websocket)
for test_console.sh: loads the live console, waits for the rank rows, SIGKILLs
a gather rank, waits for its row to turn red, clicks "pause drive", takes
screenshots.  Prints one line per finding; exit status 0 when all held.

usage: console_cdp.py DEVTOOLS_DIR URL N_RANKS KILL_RANK KILL_PID_FILE OUT_DIR
"""
import base64
import json
import os
import signal
import sys
import time
import urllib.request

import websocket  # python3-websocket

devdir, url, n_ranks, kill_rank, pid_file, out = sys.argv[1:7]
n_ranks, kill_rank = int(n_ranks), int(kill_rank)


def devtools_port():
    path = os.path.join(devdir, "DevToolsActivePort")
    for _ in range(300):
        if os.path.exists(path) and open(path).read().strip():
            return int(open(path).read().split()[0])
        time.sleep(0.1)
    sys.exit("FAIL: chromium wrote no DevToolsActivePort in 30 s")


port = devtools_port()
targets = json.load(urllib.request.urlopen("http://127.0.0.1:%d/json/list" % port, timeout=10))
page = next(t for t in targets if t.get("type") == "page")
ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=30)
seq = [0]


def call(method, **params):
    seq[0] += 1
    ws.send(json.dumps({"id": seq[0], "method": method, "params": params}))
    while True:
        m = json.loads(ws.recv())
        if m.get("id") == seq[0]:
            if "error" in m:
                raise RuntimeError("%s: %s" % (method, m["error"]))
            return m.get("result", {})


def js(expr):
    r = call("Runtime.evaluate", expression=expr, returnByValue=True)
    return r.get("result", {}).get("value")


def wait(expr, seconds, what):
    t0 = time.time()
    while time.time() - t0 < seconds:
        v = js(expr)
        if v:
            return v, time.time() - t0
        time.sleep(0.2)
    return None, time.time() - t0


def shot(name):
    data = call("Page.captureScreenshot", format="png", captureBeyondViewport=True)["data"]
    with open(os.path.join(out, name), "wb") as f:
        f.write(base64.b64decode(data))


ok = True
call("Page.enable")
call("Emulation.setDeviceMetricsOverride", width=1300, height=1500, deviceScaleFactor=1, mobile=False)
call("Page.navigate", url=url)
rows, dt = wait("document.querySelectorAll('#ranks tr.rank').length === %d && "
                "document.getElementById('conn').textContent === 'live' && "
                "Array.from(document.querySelectorAll('#ranks tr.rank')).map(r => r.cells[0].textContent + ' ' + "
                "r.cells[2].textContent + ' ' + r.cells[3].textContent + ' ' + r.cells[7].textContent).join('; ')"
                % n_ranks, 40, "rows")
if rows:
    print("ok: the page shows %d rank rows after %.1f s, live: %s" % (n_ranks, dt, rows))
else:
    ok = False
    print("FAIL: %d rank rows not seen in 40 s: %s" % (n_ranks, js("document.getElementById('ranks').innerText")))
# the plots and the images came with the events
drawn, _ = wait("document.body.dataset.frame > 5 && document.getElementById('i_projector').naturalWidth > 0 && "
                "document.getElementById('i_projector').naturalWidth", 30, "images")
print(("ok: frame %s on the page, the projector montage is %s px wide" % (js("document.body.dataset.frame"), drawn))
      if drawn else "FAIL: no montage image on the page: %s" % js("document.getElementById('n_projector').textContent"))
ok &= bool(drawn)
shot("console_before.png")

pid = int(open(pid_file).read())
os.kill(pid, signal.SIGKILL)
t_kill = time.time()
red, dt = wait("(() => { const r = document.querySelector('#ranks tr.rank[data-rank=\"%d\"]'); if (!r || "
               "!r.classList.contains('dead')) return null; return getComputedStyle(r.cells[0]).backgroundColor + ' | ' "
               "+ r.innerText.replace(/\\t/g, ' '); })()" % kill_rank, 60, "red")
if red and red.startswith("rgb(238, 51, 51)"):
    print("ok: rank %d (gather) SIGKILLed; its row turned red %.1f s later: %s" % (kill_rank, dt, red))
else:
    ok = False
    print("FAIL: rank %d's row did not turn red within 60 s of the kill: %s" % (kill_rank, red))
others = js("document.querySelectorAll('#ranks tr.rank.dead').length")
print(("ok: only that row is red" if others == 1 else "FAIL: %s rows are red" % others))
ok &= others == 1
# a control from the page: the master pauses the drive's clock
js("document.getElementById('b_pause').click()")
paused, dt = wait("document.getElementById('paused').textContent", 20, "paused")
print(("ok: 'pause drive' clicked: the page says '%s' %.1f s later" % (paused, dt)) if paused
      else "FAIL: the page never said paused")
ok &= bool(paused)
shot("console.png")
js("document.getElementById('b_resume').click()")
ws.close()
# the browser closes itself, so that xvfb-run ends and takes its Xvfb along
try:
    bws = json.load(urllib.request.urlopen("http://127.0.0.1:%d/json/version" % port, timeout=10))["webSocketDebuggerUrl"]
    b = websocket.create_connection(bws, timeout=10)
    b.send(json.dumps({"id": 1, "method": "Browser.close"}))
    b.close()
except Exception as e:  # noqa: BLE001 (the shell ends it then)
    print("NOTE: Browser.close: %s" % e)
sys.exit(0 if ok else 1)
