"""The study's fork server (platcal.study.forkserver): a job's script runs in a child of the server
as it would in its own interpreter (output, exit status, working directory, environment), the
server refuses what it cannot run alike, a killed client takes its job with it, and the child's
cost lands beside the job's benchmark file, where the timing table reads it."""

import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from platcal.study import forkclient, forkserver, timing

# a job script as Snakemake writes it: a preamble defining ``snakemake``, then the script, whose
# first statement hands the job to the server
SCRIPT = textwrap.dedent("""\
    import types
    snakemake = types.SimpleNamespace(rule="work", wildcards={"case": "a1"})
    from platcal.study.forkclient import delegate
    delegate(snakemake)
    import os, sys, time
    print("pid", os.getpid(), "ppid", os.getppid(), "cwd", os.getcwd(), "foo", os.environ.get("FOO"), flush=True)
    mode = sys.argv[1] if len(sys.argv) > 1 else ""
    if mode == "exit3":
        sys.exit(3)
    if mode == "raise":
        raise ValueError("broken job")
    if mode == "sleep":
        open(sys.argv[2], "w").write(str(os.getpid()))
        time.sleep(60)
    """)


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """A server (preloading numba's target, as the workflow's does) and the jobs' environment."""
    d = tmp_path_factory.mktemp("fs")
    scripts = d / "scripts"
    scripts.mkdir()
    (scripts / "job.py").write_text("import json\nfrom platcal.study import timing\n")
    saved = dict(os.environ)
    proc = forkserver.start(d / "sock", scripts, [], {"work": "bench/work/{case}.tsv"}, wait_s=120)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    os.environ.clear()
    os.environ.update(saved)
    assert proc.poll() is None and Path(env[forkclient.ENV_VAR]).exists(), "the server did not start"
    yield proc, env, d
    forkserver.stop(proc)


def run(script: Path, env: dict, cwd: Path, *args, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(script), *args], env=env, cwd=cwd, capture_output=True,
                          text=True, timeout=120, **kw)


def facts(out: str) -> dict:
    words = out.split("pid", 1)[1].split()
    return {"pid": int(words[0]), "ppid": int(words[2]), "cwd": words[4], "foo": words[6]}


def test_a_job_runs_in_a_child_of_the_server_with_the_clients_cwd_env_and_output(server, tmp_path):
    proc, env, _ = server
    script = tmp_path / "job.py"
    script.write_text(SCRIPT)
    r = run(script, dict(env, FOO="bar"), tmp_path)
    assert r.returncode == 0, r.stderr
    f = facts(r.stdout)
    assert f["ppid"] == proc.pid  # forked by the server, not run by the client
    assert (f["cwd"], f["foo"]) == (str(tmp_path), "bar")
    cost = json.loads((tmp_path / "bench/work/a1.worker.json").read_text())
    assert cost["cpu_s"] > 0 and cost["max_rss_mb"] > 10 and cost["wall_s"] > 0


def test_exit_status_and_traceback_are_the_scripts(server, tmp_path):
    _, env, _ = server
    script = tmp_path / "job.py"
    script.write_text(SCRIPT)
    assert run(script, env, tmp_path, "exit3").returncode == 3
    r = run(script, env, tmp_path, "raise")
    assert r.returncode == 1 and "ValueError: broken job" in r.stderr


def test_a_job_with_other_threads_or_no_server_runs_in_its_own_interpreter(server, tmp_path):
    proc, env, _ = server
    script = tmp_path / "job.py"
    script.write_text(SCRIPT)
    stale = tmp_path / "bench/work/a1.worker.json"
    stale.parent.mkdir(parents=True)
    stale.write_text("{}")
    r = run(script, dict(env, OMP_NUM_THREADS="2"), tmp_path)  # numba's and BLAS's threads: fixed at import
    assert r.returncode == 0 and facts(r.stdout)["ppid"] != proc.pid
    assert not stale.exists()  # Snakemake's figures are this run's: no worker's beside them
    r = run(script, dict(env, NUMBA_OPT="1"), tmp_path)
    assert r.returncode == 0 and facts(r.stdout)["ppid"] != proc.pid
    r = run(script, {k: v for k, v in env.items() if k not in ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS")}, tmp_path)
    assert r.returncode == 0 and facts(r.stdout)["ppid"] != proc.pid  # no thread count: every core
    r = run(script, dict(env, **{forkclient.ENV_VAR: str(tmp_path / "none.sock")}), tmp_path)
    assert r.returncode == 0 and facts(r.stdout)["ppid"] != proc.pid


def wait_gone(pid: int, seconds: float = 10.0) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def started(pidfile: Path) -> int:
    end = time.monotonic() + 60
    while not (pidfile.exists() and pidfile.read_text()) and time.monotonic() < end:
        time.sleep(0.05)
    return int(pidfile.read_text())


@pytest.mark.parametrize("how", ["SIGTERM", "SIGKILL"])
def test_a_stopped_or_killed_client_takes_its_job_with_it(server, tmp_path, how):
    _, env, _ = server
    script = tmp_path / "job.py"
    script.write_text(SCRIPT)
    pidfile = tmp_path / "child.pid"
    client = subprocess.Popen([sys.executable, str(script), "sleep", str(pidfile)], env=env, cwd=tmp_path,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    child = started(pidfile)
    assert child != client.pid
    client.send_signal(getattr(signal, how))
    status = client.wait(timeout=30)
    assert wait_gone(child), "the job outlived its client"
    if how == "SIGTERM":  # forwarded: the job ends by it, and the client says so as a shell would
        assert status == 128 + signal.SIGTERM


def test_the_server_ends_with_its_parent(tmp_path):
    code = textwrap.dedent(f"""\
        import os, sys
        from platcal.study import forkserver
        p = forkserver.start({str(tmp_path)!r}, None, [], {{}}, wait_s=120)
        print(p.pid, flush=True)
        os._exit(0)  # as a killed Snakemake would: no onsuccess, no onerror
        """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=180)
    assert wait_gone(int(r.stdout.split()[0]), 20.0)


def test_script_imports_are_the_scripts_top_level_modules(tmp_path):
    (tmp_path / "a.py").write_text("import os\nfrom platcal.study import timing\nfrom . import x\n"
                                   "def f():\n    import json\n")
    assert forkserver.script_imports(tmp_path) == ["os", "platcal.study"]


def test_the_timing_table_takes_a_workers_cost_only_from_the_same_run(tmp_path):
    tsv = tmp_path / "centrifuge/montecarlo_cell/table1_noise10.tsv"
    tsv.parent.mkdir(parents=True)
    tsv.write_text("s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"
                   "2.5\t0:00:02\t25.0\t30\t15\t17\t0\t0\t0\t0.07\n")
    side = tsv.with_suffix(".worker.json")
    side.write_text(json.dumps({"cpu_s": 2.25, "max_rss_mb": 300.0, "wall_s": 2.4}))
    now = time.time()
    os.utime(side, (now - 1, now - 1))
    os.utime(tsv, (now, now))
    row = timing.read_benchmarks(tmp_path).iloc[0]
    assert (row.cpu_s, row.max_rss_mb, row.wall_s) == (2.25, 300.0, 2.5)
    os.utime(side, (now - 2 * timing.WORKER_LAG_S, now - 2 * timing.WORKER_LAG_S))  # an older run's
    row = timing.read_benchmarks(tmp_path).iloc[0]
    assert (row.cpu_s, row.max_rss_mb) == (0.07, 25.0)


def test_a_job_of_another_interpreter_is_refused(server, tmp_path):
    """A conda environment's or a container's Python: the server, the workflow's own, cannot run it."""
    _, env, _ = server
    script = tmp_path / "job.py"
    script.write_text(SCRIPT)
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.connect(env[forkclient.ENV_VAR])
    other = ["/opt/env/bin/python", "/opt/env", forkclient.interpreter()[2]]
    forkclient.send_message(sock, {"argv": [str(script)], "cwd": str(tmp_path), "env": env, "bench": "",
                            "python": other}, (1, 2))
    reply, _ = forkclient.recv_message(sock)
    sock.close()
    assert reply == {"refused": "another interpreter (/opt/env/bin/python)"}


def test_a_workflow_folder_of_any_length_gets_a_server_and_leaves_no_socket(tmp_path):
    """A Unix socket's path is at most 107 bytes; a workflow's folder may be longer."""
    deep = tmp_path / ("x" * 60) / ("y" * 60)
    saved = dict(os.environ)
    try:
        proc = forkserver.start(deep, None, [], {}, wait_s=120)
        path = Path(os.environ[forkclient.ENV_VAR])
        assert path.exists() and proc.poll() is None
        assert path.parent.stat().st_mode & 0o077 == 0  # no other user may connect
        forkserver.stop(proc)
        assert not path.parent.exists() and forkclient.ENV_VAR not in os.environ
    finally:
        os.environ.clear()
        os.environ.update(saved)


@pytest.mark.parametrize("payload", [b"not json", b"[1, 2]", b'{"argv": ["x.py"]}',
                                     b'{"argv": [1], "cwd": "/", "env": {}, "bench": "", "python": []}'])
def test_a_malformed_request_is_refused_and_the_server_goes_on(server, tmp_path, payload):
    proc, env, _ = server
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.connect(env[forkclient.ENV_VAR])
        msg = len(payload).to_bytes(4, "big") + payload
        socket.send_fds(sock, [msg], [sys.stdout.fileno(), sys.stderr.fileno()])
        sock.settimeout(30)
        reply = sock.recv(65536)
    assert b"pid" not in reply  # refused (or closed), never run
    assert proc.poll() is None  # the server lives
    script = tmp_path / "job.py"
    script.write_text(SCRIPT)
    r = run(script, env, tmp_path)
    assert r.returncode == 0, r.stderr
    assert facts(r.stdout)["ppid"] == proc.pid  # and still serves


def test_messages_sent_back_to_back_are_read_one_at_a_time():
    """A job that ends before its client reads the server's first reply leaves both replies (the
    pid, then the exit status) in the socket: each read takes one message, never the next one's
    bytes (a quick job on a busy machine had failed with "Extra data")."""
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    with a, b:
        forkclient.send_message(a, {"pid": 12345})
        forkclient.send_message(a, {"status": 3})
        assert forkclient.recv_message(b) == ({"pid": 12345}, [])
        assert forkclient.recv_message(b) == ({"status": 3}, [])
        a.close()
        assert forkclient.recv_message(b) == (None, [])


def test_a_request_and_its_descriptors_are_read_alone():
    """The server's read of a request (with the client's stdout and stderr) takes that message
    and its descriptors only, whatever follows it in the socket."""
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    r, w = os.pipe()
    try:
        with a, b:
            forkclient.send_message(a, {"argv": ["job.py"]}, (r, w))
            forkclient.send_message(a, {"next": 1})
            msg, fds = forkclient.recv_message(b, 2)
            assert msg == {"argv": ["job.py"]} and len(fds) == 2
            for fd in fds:
                os.close(fd)
            assert forkclient.recv_message(b) == ({"next": 1}, [])
    finally:
        os.close(r)
        os.close(w)
