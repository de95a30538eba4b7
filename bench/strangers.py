#!/usr/bin/env python3
"""What sockets from one address can make the proxy hold (issue 25, items 2 and 5).

    bench/strangers.py watchers [--watchers 6] [--strokes 40] [--binary PATH] [-- PROXY-ARGS]
    bench/strangers.py pingers  [--sockets 100] [--seconds 60] [--binary PATH] [-- PROXY-ARGS]

Starts the proxy (default target/debug/penmesh-proxy) on a free port with a fresh SQLite file
and the arguments after `--`, then:

  watchers  opens WATCHERS JSON connections that say hello and never read (a 4 KiB receive
            buffer), while one drawer draws STROKES zigzag strokes (every sample retained,
            batches of 1000) and reads its answers; prints the proxy's resident memory before,
            at the end of the drawing, and 5, 20 and 60 s later, with the watchers it holds.
  pingers   opens SOCKETS connections (50 per session) that say hello and then only ping
            (a `ping` message and a WebSocket ping every 5 s; a pen at rest pings every 20 s),
            then connects once more as another client (`X-Forwarded-For: 203.0.113.9`, read
            with --trust-forwarded-for) and prints the answer; then prints how many
            connections the proxy holds every 30 s for SECONDS.

Only the standard library: the WebSocket client is the few lines it needs.
"""

import argparse
import base64
import json
import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
import uuid

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return 0.0


def start_proxy(binary, args):
    work = tempfile.mkdtemp(prefix="penmesh-strangers-")
    port = free_port()
    env = dict(os.environ, RUST_LOG="warn")
    proc = subprocess.Popen(
        [binary, "--host", "127.0.0.1", "--port", str(port),
         "--database-url", f"sqlite://{work}/p.db", *args],
        env=env, stdout=subprocess.DEVNULL, stderr=open(f"{work}/log", "w"))
    for _ in range(400):
        try:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/readyz", timeout=1)
            return proc, port, work
        except Exception:
            time.sleep(0.05)
    raise SystemExit(f"the proxy did not start (log: {work}/log)")


def create_session(port):
    req = urllib.request.Request(f"http://127.0.0.1:{port}/v1/sessions", method="POST", data=b"")
    body = json.load(urllib.request.urlopen(req))
    return body["session"], body["token"]


class Ws:
    """A WebSocket client on a raw socket."""

    def __init__(self, port, session, token, rcvbuf=None, forwarded=None):
        self.sock = socket.socket()
        if rcvbuf:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.connect(("127.0.0.1", port))
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((
            f"GET /v1/sessions/{session}/ws HTTP/1.1\r\nHost: 127.0.0.1\r\n"
            f"Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
            f"Sec-WebSocket-Version: 13\r\nAuthorization: Bearer {token}\r\n"
            + (f"X-Forwarded-For: {forwarded}\r\n" if forwarded else "") + "\r\n").encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            if not chunk:
                break
            head += chunk
        self.status = head.split(b"\r\n", 1)[0].decode(errors="replace")
        self.rest = b""
        if " 101 " not in self.status:
            self.sock.settimeout(2)
            try:
                while True:
                    chunk = self.sock.recv(4096)
                    if not chunk:
                        break
                    self.rest += chunk
            except OSError:
                pass

    def drain(self):
        """Reads and drops whatever has come (a client at rest reads its pongs)."""
        self.sock.setblocking(False)
        try:
            while self.sock.recv(1 << 16):
                pass
        except OSError:
            pass
        finally:
            self.sock.setblocking(True)

    def send(self, opcode, payload):
        mask = os.urandom(4)
        n = len(payload)
        if n < 126:
            head = struct.pack("!BB", 0x80 | opcode, 0x80 | n)
        elif n < 65536:
            head = struct.pack("!BBH", 0x80 | opcode, 0x80 | 126, n)
        else:
            head = struct.pack("!BBQ", 0x80 | opcode, 0x80 | 127, n)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
        self.sock.sendall(head + mask + masked)

    def send_json(self, msg):
        self.send(0x1, json.dumps(msg).encode())

    def recv_exact(self, n):
        out = b""
        while len(out) < n:
            chunk = self.sock.recv(n - len(out))
            if not chunk:
                raise ConnectionError("closed")
            out += chunk
        return out

    def recv(self):
        """(opcode, payload) of the next frame."""
        b0, b1 = self.recv_exact(2)
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack("!H", self.recv_exact(2))[0]
        elif n == 127:
            n = struct.unpack("!Q", self.recv_exact(8))[0]
        return b0 & 0x0F, self.recv_exact(n)


def connections(port):
    """The proxy's open WebSocket connections (its `penmesh_ws_connections` gauge)."""
    text = urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics").read().decode()
    for line in text.splitlines():
        if line.startswith("penmesh_ws_connections "):
            return int(float(line.split()[1]))
    return 0


def hello(ws):
    ws.send_json({"hello": {"protocol": 3, "client": "strangers", "resume": []}})


def watchers(args, port, proc):
    session, token = create_session(port)
    quiet = []
    for _ in range(args.watchers):
        ws = Ws(port, session, token, rcvbuf=4096)
        hello(ws)
        quiet.append(ws)
    drawer = Ws(port, session, token)
    hello(drawer)

    def read_all():
        try:
            while True:
                drawer.recv()
        except Exception:
            pass

    threading.Thread(target=read_all, daemon=True).start()
    time.sleep(1)
    before = rss_mb(proc.pid)
    peak = before
    batch = 1000
    for k in range(args.strokes):
        stroke = str(uuid.uuid4())
        drawer.send_json({"stroke_begin": {"stroke": stroke}})
        n = 5 * batch
        for b in range(0, n, batch):
            pts = [[(b + i) * 4.0, 0.0 if (b + i) % 2 == 0 else 50.0, float(b + i), 0.5]
                   for i in range(batch)]
            drawer.send_json({"points": {"stroke": stroke, "seq": b, "points": pts}})
        drawer.send_json({"stroke_end": {"stroke": stroke, "n_points": n}})
        time.sleep(0.05)
        peak = max(peak, rss_mb(proc.pid))
    time.sleep(1)
    end = rss_mb(proc.pid)
    peak = max(peak, end)
    print(f"watchers {args.watchers}, strokes {args.strokes} x 5000 zigzag samples")
    print(f"RSS before {before:.0f} MB, peak {peak:.0f} MB, at the end of the drawing {end:.0f} MB")
    for wait in (5, 15, 40):
        time.sleep(wait)
        print(f"  then {wait} s more: RSS {rss_mb(proc.pid):.0f} MB, "
              f"connections open {connections(port)} ({args.watchers} watchers and the drawer)")


def pingers(args, port, proc):
    held = []
    for i in range(args.sockets):
        if i % 50 == 0:
            session, token = create_session(port)
        ws = Ws(port, session, token)
        if " 101 " not in ws.status:
            print(f"socket {i}: {ws.status} {ws.rest[-300:].decode(errors='replace')}")
            break
        hello(ws)
        held.append(ws)
    print(f"opened {len(held)} pinging sockets")
    # Another client: another address when the proxy trusts X-Forwarded-For.
    other, other_token = create_session(port)
    ws = Ws(port, other, other_token, forwarded="203.0.113.9")
    print(f"a new session's connection from another address: {ws.status} "
          f"{ws.rest[-300:].decode(errors='replace')}")
    start = time.time()
    while time.time() - start < args.seconds:
        time.sleep(5)
        for ws in held:
            try:
                ws.drain()
                ws.send_json({"ping": {"nonce": 1}})
                ws.send(0x9, b"")
            except OSError:
                pass
        if int(time.time() - start) % 30 < 5:
            print(f"{time.time() - start:5.0f} s: {connections(port)} connections open")


def main():
    argv = sys.argv[1:]
    proxy_args = []
    if "--" in argv:
        i = argv.index("--")
        argv, proxy_args = argv[:i], argv[i + 1:]
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("what", choices=["watchers", "pingers"])
    parser.add_argument("--binary", default=os.path.join(ROOT, "target", "debug", "penmesh-proxy"))
    parser.add_argument("--watchers", type=int, default=6)
    parser.add_argument("--strokes", type=int, default=40)
    parser.add_argument("--sockets", type=int, default=100)
    parser.add_argument("--seconds", type=int, default=60)
    args = parser.parse_args(argv)
    proc, port, work = start_proxy(args.binary, proxy_args)
    try:
        if args.what == "watchers":
            watchers(args, port, proc)
        else:
            pingers(args, port, proc)
    finally:
        proc.terminate()
        proc.wait()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
