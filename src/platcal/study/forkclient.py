"""The client side of the study's fork server (:mod:`platcal.study.forkserver`): what every
workflow script runs first, :func:`delegate`, and the few pieces the server shares with it.

A module of its own with the standard library and Snakemake's wildcard formatting only: the job's
interpreter imports it before anything else, and whatever it imported every job would pay.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import struct
import sys
from pathlib import Path

from snakemake.io import apply_wildcards

ENV_VAR = "PLATCAL_FORKSERVER"
"""The environment variable naming the server's socket in the workflow's jobs."""

_HEADER = struct.Struct("!I")


def interpreter() -> list:
    """This interpreter: its executable, prefix and version. A job of a conda environment or a
    container has another: the server (the workflow's own) cannot run it."""
    return [sys.executable, sys.prefix, sys.version]


def send_message(sock: socket.socket, obj: dict, fds: tuple = ()) -> None:
    """``obj`` as JSON behind its length (and the file descriptors ``fds`` with it)."""
    data = json.dumps(obj).encode()
    msg = _HEADER.pack(len(data)) + data
    if fds:
        socket.send_fds(sock, [msg], list(fds))
    else:
        sock.sendall(msg)


def recv_message(sock: socket.socket, nfds: int = 0) -> tuple[dict | None, list]:
    """One message (and up to ``nfds`` file descriptors); ``(None, [])`` when the peer closed.

    Reads no byte past the message: the server sends a job's pid and then its exit status, and
    a quick job's status may already wait behind the pid when the client reads."""
    buf, fds = b"", []
    while len(buf) < _HEADER.size:
        if nfds and not fds:
            chunk, fds, _, _ = socket.recv_fds(sock, _HEADER.size - len(buf), nfds)
        else:
            chunk = sock.recv(_HEADER.size - len(buf))
        if not chunk:
            return None, fds
        buf += chunk
    (size,) = _HEADER.unpack(buf[:_HEADER.size])
    buf = buf[_HEADER.size:]
    while len(buf) < size:
        chunk = sock.recv(size - len(buf))
        if not chunk:
            return None, fds
        buf += chunk
    return json.loads(buf), fds


def worker_file(bench) -> Path:
    """Where the server writes a forked job's own cost: ``<job>.worker.json`` beside its
    benchmark file ``<job>.tsv``."""
    return Path(bench).with_suffix(".worker.json")


# ---- the client: the first statement of every workflow script

def bench_of(sm) -> str:
    """The job's benchmark file, from the pattern the workflow gives the server's environment
    (``PLATCAL_FORKSERVER_BENCH``: rule -> pattern) and the job's wildcards; empty if none."""
    patterns = json.loads(os.environ.get(f"{ENV_VAR}_BENCH", "{}"))
    pattern = patterns.get(getattr(sm, "rule", ""), "")
    return apply_wildcards(pattern, dict(sm.wildcards.items())) if pattern else ""


def delegate(sm) -> None:
    """Run this job's script in the study's fork server and exit with its status; return (and so
    run the job here) when no server answers or it refuses the job. ``sm``: the script's
    ``snakemake`` object (for the job's benchmark file)."""
    path = os.environ.get(ENV_VAR)
    if not path:
        return
    bench = bench_of(sm)
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.connect(path)
        env = {k: v for k, v in os.environ.items() if not k.startswith(ENV_VAR)}
        argv = [os.path.abspath(sys.argv[0]), *sys.argv[1:]]
        send_message(sock, {"argv": argv, "cwd": os.getcwd(), "env": env, "bench": bench, "python": interpreter()},
                     (sys.stdout.fileno(), sys.stderr.fileno()))
        reply, _ = recv_message(sock)
    except OSError:
        reply = None
    if reply is None or "pid" not in reply:  # no server, or refused: this interpreter runs the job
        sock.close()
        if bench:  # Snakemake's own figures are this job's: no stale worker's beside them
            worker_file(bench).unlink(missing_ok=True)
        return
    pid = reply["pid"]

    def forward(signum, frame):
        try:
            os.kill(pid, signum)
        except ProcessLookupError:
            pass

    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, forward)
    done, _ = recv_message(sock)
    sys.stdout.flush()
    sys.stderr.flush()
    if done is None:
        sys.stderr.write("platcal fork server: the server closed the connection before the job ended\n")
        os._exit(1)
    os._exit(int(done["status"]))
