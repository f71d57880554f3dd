#!/usr/bin/env python3
"""Abuses the live console's HTTP server for test_console.sh (all on this
machine): at once, for SECONDS,
  flood      1000 concurrent TCP connections, opened together and held idle;
  slowloris  50 partial requests, one header byte a second, never finished;
  oversize   20 requests with a 1 MiB header;
  malformed  bad methods, request lines without a version, a TLS hello, a
             100 KiB request line, NUL bytes.
Then the server must answer a normal GET /metrics again.  Writes a JSON
summary: per kind the connections, how many the server closed, the status
codes seen, the longest time from a client's last byte to the server's close.

usage: console_abuse.py HOST PORT SECONDS OUT.json
"""
import json
import resource
import selectors
import socket
import sys
import time
import urllib.request

host, port, secs, out = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
try:
    resource.setrlimit(resource.RLIMIT_NOFILE, (8192, 8192))
except (ValueError, OSError):
    pass

sel = selectors.DefaultSelector()
conns = []
t_start = time.time()

MALFORMED = [b"BREW / HTTP/1.1\r\nHost: x\r\n\r\n", b"DELETE /metrics HTTP/1.1\r\nHost: x\r\n\r\n",
             b"GET /\r\n\r\n", b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03" + b"\x00" * 64,
             b"GET /" + b"a" * (100 * 1024) + b" HTTP/1.1\r\nHost: x\r\n\r\n",
             b"GET / HTTP/1.1\r\nHost: x\r\nContent-Length: -5\r\n\r\n", b"\x00\x00\x00\x00\r\n\r\n",
             b"GET / HTTP/9.9\r\nHost: x\r\n\r\n", b"POST /control HTTP/1.1\r\nHost: x\r\nContent-Length: 99999999\r\n\r\nabc"]


def open_conn(kind, payload=b"", trickle=False):
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.setblocking(False)
    s.connect_ex((host, port))
    c = {"kind": kind, "sock": s, "out": payload, "trickle": trickle, "t0": time.time(), "connected": False,
         "closed": None, "last_send": None, "got": b"", "next": 0.0}
    conns.append(c)
    sel.register(s, selectors.EVENT_READ | selectors.EVENT_WRITE, c)


def close(c, now):
    if c["closed"] is None:
        c["closed"] = now
        try:
            sel.unregister(c["sock"])
        except (KeyError, ValueError):
            pass
        c["sock"].close()


def on_event(c, mask, now):
    s = c["sock"]
    if mask & selectors.EVENT_WRITE:
        if not c["connected"]:
            if s.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR):
                close(c, now)
                return
            c["connected"] = True
        if c["out"]:
            try:
                n = s.send(c["out"])
                c["out"] = c["out"][n:]
                c["last_send"] = now
            except (BlockingIOError, InterruptedError):
                pass
            except OSError:
                close(c, now)
                return
        if not c["out"]:
            sel.modify(s, selectors.EVENT_READ, c)
    if mask & selectors.EVENT_READ:
        try:
            d = s.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            close(c, now)
            return
        if not d:
            close(c, now)
        elif len(c["got"]) < 256:
            c["got"] += d[:256]


for i in range(1000):
    open_conn("flood")
for i in range(50):
    open_conn("slowloris", b"GET /metrics HTTP/1.1\r\nHost: x\r\n", trickle=True)
for i in range(20):
    open_conn("oversize", b"GET /metrics HTTP/1.1\r\nHost: x\r\nX-Big: " + b"a" * (1 << 20) + b"\r\n\r\n")
for i in range(50):
    open_conn("malformed", MALFORMED[i % len(MALFORMED)])

deadline = t_start + secs
while time.time() < deadline and any(c["closed"] is None for c in conns):
    now = time.time()
    for key, mask in sel.select(timeout=0.05):
        on_event(key.data, mask, now)
    for c in conns:  # slowloris: one byte a second
        if c["trickle"] and c["closed"] is None and c["connected"] and now >= c["next"]:
            try:
                c["sock"].send(b"X")
                c["last_send"] = now
            except OSError:
                close(c, now)
            c["next"] = now + 1.0
# the clients stop sending: how long until the server closes what is left
t_stop = time.time()
while time.time() < t_stop + 20 and any(c["closed"] is None for c in conns):
    for key, mask in sel.select(timeout=0.05):
        if mask & selectors.EVENT_READ:
            on_event(key.data, selectors.EVENT_READ, time.time())
t_end = time.time()

summary = {"seconds": round(t_end - t_start, 2)}
for kind in ("flood", "slowloris", "oversize", "malformed"):
    cs = [c for c in conns if c["kind"] == kind]
    codes = {}
    for c in cs:
        line = c["got"].split(b"\r\n", 1)[0].decode("latin-1")
        code = line.split()[1] if line.startswith("HTTP/") and len(line.split()) > 1 else "none"
        codes[code] = codes.get(code, 0) + 1
    after = [c["closed"] - (c["last_send"] or c["t0"]) for c in cs if c["closed"] is not None]
    summary[kind] = {"connections": len(cs), "connected": sum(c["connected"] for c in cs),
                     "closed": sum(c["closed"] is not None for c in cs), "codes": codes,
                     "close_after_last_byte_max_s": round(max(after), 2) if after else None}
    for c in cs:
        if c["closed"] is None:
            c["sock"].close()
# the server answers again
t0 = time.time()
status = None
while time.time() - t0 < 15 and status != 200:
    try:
        status = urllib.request.urlopen("http://%s:%d/metrics" % (host, port), timeout=5).status
    except Exception as e:  # noqa: BLE001 (any failure: try again)
        status = str(e)
        time.sleep(0.5)
summary["after"] = {"status": status, "seconds": round(time.time() - t0, 2)}
json.dump(summary, open(out, "w"), indent=1)
print(json.dumps(summary))
