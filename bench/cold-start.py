#!/usr/bin/env python3
"""Cold start of the proxy: from exec to the first 200 on /readyz, median of N runs.

    bench/cold-start.py [--runs 20] [--postgres postgres://postgres@127.0.0.1:5432/test]

Runs target/release/penmesh-proxy (build it first: cargo build --release -p penmesh-proxy)
with the image's settings (deploy/Dockerfile: PENMESH_HOST, a SQLite file in an empty
working directory, or PostgreSQL), polls /readyz every 0.5 ms over a fresh TCP connection,
then stops it with SIGTERM before the next run. Cases:
  sqlite, new file       a first start: the file is created and migrated
  sqlite, existing file  a restart
  postgres, migrated     what a scale-from-zero instance does (the database exists)
  postgres, new database a first start on an empty database (migrations)
"""

import argparse
import os
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BINARY = os.path.join(ROOT, "target", "release", "penmesh-proxy")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def ready(port):
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1) as s:
            s.sendall(b"GET /readyz HTTP/1.0\r\n\r\n")
            return s.recv(64).split(b"\r\n", 1)[0].endswith(b" 200 OK")
    except OSError:
        return False


def one_start(database_url, workdir):
    port = free_port()
    env = {
        "PATH": os.environ.get("PATH", "/usr/bin:/bin"),
        "PORT": str(port),
        "PENMESH_HOST": "0.0.0.0",
        "PENMESH_DATABASE_URL": database_url,
    }
    started = time.perf_counter()
    proxy = subprocess.Popen(
        [BINARY], env=env, cwd=workdir, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    try:
        while not ready(port):
            if proxy.poll() is not None:
                sys.exit(f"the proxy exited: {proxy.stderr.read().decode(errors='replace')}")
            if time.perf_counter() - started > 30:
                sys.exit("no 200 on /readyz within 30 s")
            time.sleep(0.0005)
        elapsed_ms = (time.perf_counter() - started) * 1000
    finally:
        proxy.send_signal(signal.SIGTERM)
        if proxy.wait(timeout=15) != 0:
            sys.exit(f"the proxy stopped with status {proxy.returncode}")
    return elapsed_ms


def psql(url, command):
    subprocess.run(["psql", url, "-qc", command], check=True, stdout=subprocess.DEVNULL)


def measure(name, runs, start):
    times = [start(i) for i in range(runs)]
    print(
        f"| {name} | {runs} | {statistics.median(times):.1f} | {min(times):.1f} "
        f"| {max(times):.1f} |",
        flush=True,
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--postgres", help="an admin URL; databases penmesh_cold_* are made")
    args = parser.parse_args()
    if not os.access(BINARY, os.X_OK):
        sys.exit(f"{BINARY} missing: cargo build --release -p penmesh-proxy")
    load = os.getloadavg()[0]
    print(f"load average at start: {load:.2f}; {os.cpu_count()} CPUs")
    print("| case | runs | median ms | min ms | max ms |")
    print("|---|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:

        def sqlite_new(i):
            workdir = os.path.join(tmp, f"new-{i}")
            os.mkdir(workdir)
            try:
                return one_start(f"sqlite://{workdir}/penmesh.db", workdir)
            finally:
                shutil.rmtree(workdir)

        measure("SQLite, new file", args.runs, sqlite_new)
        existing = os.path.join(tmp, "existing")
        os.mkdir(existing)
        url = f"sqlite://{existing}/penmesh.db"
        one_start(url, existing)
        measure("SQLite, existing file", args.runs, lambda i: one_start(url, existing))

    if args.postgres:
        base = args.postgres.rsplit("/", 1)[0]
        migrated = f"penmesh_cold_{os.getpid()}"
        psql(args.postgres, f"CREATE DATABASE {migrated}")
        try:
            one_start(f"{base}/{migrated}", ROOT)
            measure(
                "PostgreSQL, migrated database",
                args.runs,
                lambda i: one_start(f"{base}/{migrated}", ROOT),
            )

            def postgres_new(i):
                name = f"{migrated}_{i}"
                psql(args.postgres, f"CREATE DATABASE {name}")
                try:
                    return one_start(f"{base}/{name}", ROOT)
                finally:
                    psql(args.postgres, f"DROP DATABASE {name}")

            measure("PostgreSQL, new database", args.runs, postgres_new)
        finally:
            psql(args.postgres, f"DROP DATABASE IF EXISTS {migrated}")


if __name__ == "__main__":
    main()
