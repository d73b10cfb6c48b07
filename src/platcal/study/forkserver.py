"""The study's fork server: workflow jobs forked from one process that has already imported what
they import (issue 22 item 4).

A workflow job is a fresh interpreter (Snakemake's ``script:``), and before it computes anything
it spends 0.3-1.5 s CPU importing numpy, numba and its target, scipy, pyarrow and platcal's
modules: about a sixth of the default study's job-seconds over its 87 jobs. The workflow starts
one server per run (``onstart``, :func:`start`): it imports the modules that the workflow's
scripts import at their top, the rigs' Monte Carlo hooks and numba's CPU target, then waits on a
Unix socket. Each job's script opens with :func:`platcal.study.forkclient.delegate`: the job's
interpreter (the client) hands the server its script, arguments, working directory, environment,
standard output and error; the server forks, the child runs the script as ``__main__`` exactly as the interpreter
would, and the client waits, forwards SIGINT and SIGTERM to the child, and exits with the child's
status. The numbers do not change: the same code runs on the same inputs, each job in a process
of its own; only the imports are done once.

A job runs in the client instead (as before) when no server answers (a dry run, a cluster node,
a script run by hand) and when the server refuses it: a job whose environment differs from the
server's in what numba, BLAS and OpenMP read at import (its threads, ``NUMBA_*``): those are
fixed in the server's process when it imports them.

Snakemake's ``benchmark:`` file measures the client, which waits: its wall time is the job's, its
CPU time and peak RSS are not. The server writes the child's own (``wait4``: user + system CPU s,
peak RSS MB) beside the benchmark file, ``<job>.worker.json``, before the client exits and so
before Snakemake writes ``<job>.tsv``; :func:`platcal.study.timing.read_benchmarks` takes them
from there. A child's peak RSS counts the pages it shares with the server.

The child exits with ``os._exit`` after running the atexit handlers its job registered, flushing
its streams and shutting logging down (the server's own handlers are not run: they are not the
job's). If the client dies (SIGKILL), the child sees its connection close and ends itself, so no
job outlives its client; if the Snakemake process dies, the server ends within a second.
"""

from __future__ import annotations

import argparse
import ast
import atexit
import importlib
import json
import logging
import os
import runpy
import selectors
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from ..io import atomic_write_text
from .forkclient import ENV_VAR, interpreter, recv_message, send_message, worker_file


FIXED_AT_IMPORT = ("NUMBA_", "OMP_", "OPENBLAS_", "MKL_", "PYTHON")
"""Prefixes of the environment variables read when numba, BLAS, OpenMP or the interpreter start:
a job whose values differ from the server's runs in its own interpreter."""
JOB_THREADS = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
"""The server runs as a one-thread job does (the workflow's jobs set one BLAS thread; a job given
more threads differs in ``OMP_NUM_THREADS`` and runs in its own interpreter)."""


@dataclass(frozen=True)
class Request:
    """What a client hands the server: the script to run as ``__main__`` (``argv[0]``), its
    working directory and environment, the benchmark file of its job (relative to ``cwd``; empty
    when the rule has none) and its interpreter (:func:`interpreter`)."""

    argv: list
    cwd: str
    env: dict
    bench: str
    python: list


# ---- the server

def script_imports(folder) -> list[str]:
    """The modules that the workflow's scripts (``folder/*.py``) import at their top level."""
    names = []
    for f in sorted(Path(folder).glob("*.py")):
        for node in ast.parse(f.read_text()).body:
            if isinstance(node, ast.Import):
                names += [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                names.append(node.module)
    return list(dict.fromkeys(names))


def preload(modules, rigs) -> None:
    """Import ``modules``, each rig's Monte Carlo hooks, then numba and its CPU target (numba
    after platcal's modules, as in a job: their kernels are declared before numba loads)."""
    for name in modules:
        importlib.import_module(name)
    rig_module = importlib.import_module("platcal.rig")
    for r in rigs:
        rig_module.get_rig(r).montecarlo
    # by name: a client imports this module, and must not load numba (the server's alone does)
    importlib.import_module("numba.core.registry").cpu_target.target_context  # LLVM and the registries: 0.2 s a job


def _exit_code(exc: SystemExit) -> int:
    if exc.code is None:
        return 0
    if isinstance(exc.code, int):
        return exc.code
    print(exc.code, file=sys.stderr)
    return 1


def _run_child(req: Request, fds: list, conn: socket.socket) -> None:
    """In the forked child: become the job's process, run its script, exit with its status."""
    conn.settimeout(None)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    null = os.open(os.devnull, os.O_RDONLY)
    for target, fd in zip((0, 1, 2), [null, *fds]):
        os.dup2(fd, target)
    for fd in (null, *fds):
        os.close(fd)
    os.chdir(req.cwd)
    os.environ.clear()
    os.environ.update(req.env)
    config = sys.modules.get("numba.core.config")
    if config is not None:  # numba compares the environment with its last reading at every compile
        config.reload_config()
    sys.argv = list(req.argv)
    atexit._clear()

    def watch():  # the client gone (killed): so is its job
        try:
            conn.recv(1)
        except OSError:
            pass
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, daemon=True).start()
    code = 0
    try:
        runpy.run_path(req.argv[0], run_name="__main__")
    except SystemExit as exc:
        code = _exit_code(exc)
    except BaseException:
        traceback.print_exc()
        code = 1
    try:
        atexit._run_exitfuncs()
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(code)


def refusal(req: Request, base: dict) -> str:
    """Why the server cannot run this job ('' if it can): another interpreter, or an import-time
    setting that differs."""
    if req.python != interpreter():
        return f"another interpreter ({req.python[0]})"
    for k in sorted(set(base) | {k for k in req.env if k.startswith(FIXED_AT_IMPORT)}):
        want = base.get(k)
        if k in JOB_THREADS:
            # the job's threads: Snakemake sets OMP_NUM_THREADS (and the BLAS ones) to the rule's
            if k == "OMP_NUM_THREADS" and req.env.get(k) != want:
                return f"{k}={req.env.get(k)} (the server runs one-thread jobs)"
            continue
        if req.env.get(k) != want:
            return f"{k} differs from the server's"
    if not os.path.isfile(req.argv[0] if req.argv else ""):
        return "no script"
    return ""


def _write_cost(req: Request, wall: float, ru) -> None:
    """The child's CPU and peak RSS beside the job's benchmark file (written, then renamed)."""
    if not req.bench:
        return
    path = worker_file(Path(req.cwd, req.bench))
    path.parent.mkdir(parents=True, exist_ok=True)
    cost = {"cpu_s": ru.ru_utime + ru.ru_stime, "max_rss_mb": ru.ru_maxrss / 1024.0, "wall_s": wall}
    atomic_write_text(path, json.dumps(cost))


def serve(path: str, log=sys.stderr) -> None:
    """Accept jobs on the Unix socket ``path`` until SIGTERM or until the parent process ends."""
    parent = os.getppid()
    os.close(os.pidfd_open(os.getpid()))  # Linux >= 5.3; else this fails before any client connects
    base = {k: v for k, v in os.environ.items() if k.startswith(FIXED_AT_IMPORT)}
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    tmp = f"{path}.{os.getpid()}"
    listener.bind(tmp)
    listener.listen(64)
    os.replace(tmp, path)  # clients connect only once the imports are done
    sel = selectors.DefaultSelector()
    sel.register(listener, selectors.EVENT_READ, None)
    running = {}
    stop = []
    signal.signal(signal.SIGTERM, lambda *a: stop.append(1))
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches Snakemake, which stops its jobs' clients
    print(f"fork server {os.getpid()}: ready on {path}", file=log, flush=True)
    while not stop and os.getppid() == parent:
        for key, _ in sel.select(timeout=1.0):
            if key.data is None:
                _accept(listener, sel, running, base, log)
            else:
                _reap(key.data, sel, running)
    sel.close()
    listener.close()
    try:
        os.unlink(path)
        os.rmdir(os.path.dirname(path))
    except OSError:
        pass


def _request(msg) -> Request | None:
    """The client's message as a :class:`Request`, or None if it is not one (the job is then
    refused and the server goes on serving)."""
    try:
        req = Request(**msg)
    except TypeError:  # not a dict, or keys missing or unknown
        return None
    ok = (isinstance(req.argv, list) and req.argv and all(isinstance(a, str) for a in req.argv)
          and isinstance(req.cwd, str) and isinstance(req.bench, str) and isinstance(req.env, dict)
          and all(isinstance(k, str) and isinstance(v, str) for k, v in req.env.items()))
    return req if ok else None


def _accept(listener, sel, running, base, log) -> None:
    conn, _ = listener.accept()
    conn.settimeout(10.0)
    try:
        msg, fds = recv_message(conn, 2)
    except (OSError, ValueError):  # ValueError: not JSON
        conn.close()
        return
    req = _request(msg)
    why = "bad request" if req is None or len(fds) != 2 else refusal(req, base)
    if why:
        for fd in fds:
            os.close(fd)
        print(f"fork server: refused {req.argv[0] if req else '?'}: {why}", file=log, flush=True)
        try:
            send_message(conn, {"refused": why})
        except OSError:
            pass
        conn.close()
        return
    sys.stdout.flush()
    log.flush()
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:
        sel.close()
        listener.close()
        for pidfd, child in running.items():
            os.close(pidfd)
            child[1].close()
        _run_child(req, fds, conn)
    for fd in fds:
        os.close(fd)
    conn.settimeout(None)
    pidfd = os.pidfd_open(pid)
    running[pidfd] = (pid, conn, req, t0)
    sel.register(pidfd, selectors.EVENT_READ, pidfd)
    try:
        send_message(conn, {"pid": pid})
    except OSError:
        os.kill(pid, signal.SIGKILL)


def _reap(pidfd, sel, running) -> None:
    pid, conn, req, t0 = running.pop(pidfd)
    sel.unregister(pidfd)
    os.close(pidfd)
    _, status, ru = os.wait4(pid, 0)
    _write_cost(req, time.perf_counter() - t0, ru)
    code = os.waitstatus_to_exitcode(status)
    try:
        send_message(conn, {"status": code if code >= 0 else 128 - code})  # killed by signal s: 128 + s, as a shell says
    except OSError:
        pass
    conn.close()


# ---- the workflow's side: start and stop (Snakefile onstart, onsuccess, onerror)

def start(folder, scripts, rigs, bench: dict, wait_s: float = 0.0) -> subprocess.Popen | None:
    """Start a server for this workflow run (its log in ``folder``), preloading what the scripts
    in ``scripts`` import and the ``rigs``' hooks, and point the jobs at it (``os.environ``: the
    socket and the rules' benchmark patterns ``bench``). It answers once its imports are done
    (about 3 s); jobs that start before run in their own interpreters. ``wait_s``: wait up to
    that long for it (tests). None (every job in its own interpreter) where the system cannot
    watch a child through a file descriptor (``os.pidfd_open``: Linux only)."""
    if not hasattr(os, "pidfd_open"):
        return None
    folder = Path(folder).resolve()
    folder.mkdir(parents=True, exist_ok=True)
    # a socket's path is at most 107 bytes (a workflow's folder may be longer); a folder of mode
    # 0700, so that no other user can connect and have a script run as this one
    path = Path(tempfile.mkdtemp(prefix="platcal-fs-"), "sock")
    env = dict(os.environ, **JOB_THREADS)
    env.pop(ENV_VAR, None)
    log = open(folder / f"forkserver-{os.getpid()}.log", "w")
    cmd = [sys.executable, "-m", __name__, str(path), "--rigs", *rigs] + (["--scripts", str(scripts)] if scripts else [])
    # a session of its own: a Ctrl-C goes to Snakemake and the clients, which forward it to their jobs
    proc = subprocess.Popen(cmd, env=env, stdout=log, stderr=log, stdin=subprocess.DEVNULL, start_new_session=True)
    log.close()
    os.environ[ENV_VAR] = str(path)
    os.environ[f"{ENV_VAR}_BENCH"] = json.dumps(bench)
    deadline = time.monotonic() + wait_s
    while not path.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    return proc


def stop(proc: subprocess.Popen | None) -> None:
    """Stop the server :func:`start` started (the jobs no longer look for it)."""
    path = os.environ.pop(ENV_VAR, None)
    os.environ.pop(f"{ENV_VAR}_BENCH", None)
    if proc is not None and proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    if path and Path(path).parent.name.startswith("platcal-fs-"):  # a server that could not clean up
        shutil.rmtree(Path(path).parent, ignore_errors=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("socket")
    ap.add_argument("--scripts", help="the workflow's scripts folder: its scripts' imports are preloaded")
    ap.add_argument("--rigs", nargs="*", default=[])
    a = ap.parse_args(argv)
    t0 = time.process_time()
    preload(script_imports(a.scripts) if a.scripts else [], a.rigs)
    print(f"fork server {os.getpid()}: preloaded in {time.process_time() - t0:.2f} s CPU", file=sys.stderr, flush=True)
    serve(a.socket)
    return 0


if __name__ == "__main__":
    sys.exit(main())
