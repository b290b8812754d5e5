"""The job server: jobs run in forks of a warm process, with the same results as in-process; errors, stale
code and killed clients are handled."""

import json
import os
import pickle
import re
import signal
import socket
import stat
import struct
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from bsrbench import jobserver


@pytest.fixture
def runtime_base(monkeypatch):
    """An XDG_RUNTIME_DIR of this test's own (so no test touches the user's real one), short enough for a Unix
    socket's path (at most 107 bytes; pytest's tmp_path under pytest-xdist is longer)."""
    import shutil
    import tempfile

    base = Path(tempfile.mkdtemp(prefix="bsrjs-", dir="/tmp"))
    base.chmod(0o700)
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(base))
    monkeypatch.delenv("BSRBENCH_JOBSERVER_SOCKET", raising=False)
    yield base
    shutil.rmtree(base, ignore_errors=True)


@pytest.fixture
def server_socket(runtime_base, monkeypatch):
    """The socket of a private server for this test (started on first use), shut down afterwards."""
    monkeypatch.delenv(jobserver.OWNER_VAR, raising=False)
    for var in jobserver._BATCH_JOB_VARS:
        monkeypatch.delenv(var, raising=False)
    path = jobserver.socket_path()
    assert path.parent == runtime_base / "bsrbench"
    yield path
    jobserver.shutdown(path)


def _server_files(path):
    return sorted(p.name for p in path.parent.glob(path.name + "*"))


def _ping(tmp_path, **params):
    return {
        "input": {},
        "output": {"path": str(tmp_path / "out.txt")},
        "params": params,
        "wildcards": {},
        "log": [str(tmp_path / "ping.log")],
        "threads": 1,
    }


def _worker_pid(pid_file, timeout=60):
    """The pid a ping job's worker writes to ``pid_file`` (by a rename, so never read half-written)."""
    deadline = time.monotonic() + timeout
    while not pid_file.exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    return int(pid_file.read_text())


def _ping_client(job, **popen):
    """A client process that runs the ping ``job`` through the job server."""
    code = f"from bsrbench import jobserver; jobserver.run('bsrbench.jobserver:ping', {job!r})"
    return subprocess.Popen([sys.executable, "-c", code], env=dict(os.environ), **popen)


def test_job_runs_in_a_fork_of_one_server(server_socket, tmp_path):
    pids = []
    for _ in range(2):
        jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))
        pids.append(int((tmp_path / "out.txt").read_text()))
    assert server_socket.exists()
    assert pids[0] != pids[1] and os.getpid() not in pids  # a fresh fork per job, not this process
    assert "ping from pid" in (tmp_path / "ping.log").read_text()


@pytest.mark.parametrize("var", ["SLURM_JOB_ID", "PBS_JOBID", "LSB_JOBID"])
def test_a_job_inside_a_batch_system_job_runs_in_process(server_socket, tmp_path, monkeypatch, var):
    """On a cluster node the job runs in its own process even if the config asks for the server (a --config on
    the command line replaces the SLURM profile's job_server=False)."""
    monkeypatch.setenv(var, "4242")
    monkeypatch.setattr(sys, "stderr", sys.stderr)  # run_local points stderr at the job's log
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path), use_server=True)
    assert int((tmp_path / "out.txt").read_text()) == os.getpid()
    assert not server_socket.exists()


def test_error_reaches_the_client_and_the_log(server_socket, tmp_path):
    with pytest.raises(
        SystemExit, match=r"(?s)failed in the job server; see .*ping\.log.*ping asked to fail: boom"
    ):
        jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path, fail="boom"))
    assert "ValueError: ping asked to fail: boom" in (tmp_path / "ping.log").read_text()
    assert not (tmp_path / "out.txt").exists()


def test_stale_server_is_replaced(server_socket, tmp_path):
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.connect(str(server_socket))
        jobserver._send(s, {"fingerprint": "other code", "target": "", "job": {}, "cwd": "/"})
        assert jobserver._recv(s) == {"status": "stale", "detail": None}
    deadline = time.monotonic() + 10
    while server_socket.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not server_socket.exists()  # the stale server exited
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))  # and a new one serves
    assert (tmp_path / "out.txt").exists()


def test_killed_client_kills_its_worker(server_socket, tmp_path):
    pid_file = tmp_path / "worker.pid"
    job = _ping(tmp_path, sleep=60, pid_file=str(pid_file))
    client = _ping_client(job)
    worker = _worker_pid(pid_file)
    client.send_signal(signal.SIGKILL)
    client.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            os.kill(worker, 0)
        except ProcessLookupError:
            break
        time.sleep(0.05)
    else:
        pytest.fail(f"worker {worker} still alive after its client was killed")
    assert not (tmp_path / "out.txt").exists()


def test_fit_job_same_result_in_server_and_in_process(server_socket, tmp_path):
    rng = np.random.default_rng(0)
    features = tmp_path / "f.npz"
    np.savez(
        features, X=rng.gamma(2.0, 1.0, (80, 6)), Y=rng.uniform(-90, 90, (80, 5)), heading_column=2
    )
    rows = {}
    for mode in ("server", "local"):
        out = tmp_path / mode
        out.mkdir()
        job = {
            "input": {"features": str(features), "cv": [], "code": []},
            "output": {"row": str(out / "row.json"), "predictions": str(out / "pred.npz")},
            "params": {
                "estimator": "bsrbench.models.bsr:BayesianSR",
                "fixed": {"n_atoms": 4, "n_iter": 30, "n_burn_in": 10, "thin": 2},
                "cv_mode": "none",
                "paper_activity": "",
                "pose_transform": "none",
                "min_test": 10,
                "gap": 5,
                "job_server": True,
            },
            "wildcards": {
                "protocol": "random",
                "source": "toy",
                "activity": "a",
                "method": "PM",
                "n_train": "30",
                "seed": "1",
            },
            "log": [str(out / "job.log")],
            "threads": 1,
        }
        if mode == "server":
            jobserver.run("bsrbench.jobs:fit", job)
        else:  # a fresh interpreter, as with job_server: false
            code = f"from bsrbench import jobserver; jobserver.run('bsrbench.jobs:fit', {job!r}, use_server=False)"
            subprocess.run([sys.executable, "-c", code], check=True, env=dict(os.environ))
        rows[mode] = json.loads((out / "row.json").read_text())
        with np.load(out / "pred.npz") as f:
            rows[mode]["_pred"] = {k: f[k] for k in f.files}
    a, b = rows["server"], rows["local"]
    assert a["error"] == b["error"] and a["params"] == b["params"]
    for k in a["_pred"]:
        np.testing.assert_array_equal(a["_pred"][k], b["_pred"][k], err_msg=k)


def test_worker_killed_from_outside_is_named_by_its_signal(server_socket, tmp_path):
    """A worker killed by someone else (the out-of-memory killer sends SIGKILL) fails its job with the signal's
    name, not a raw wait status."""
    pid_file = tmp_path / "worker.pid"
    job = _ping(tmp_path, sleep=60, pid_file=str(pid_file))
    client = _ping_client(job, stderr=subprocess.PIPE, text=True)
    os.kill(_worker_pid(pid_file), signal.SIGKILL)
    _, err = client.communicate(timeout=60)
    assert client.returncode != 0
    assert "worker was killed by SIGKILL" in err and "status 9" not in err
    # the job's log, which the message points to, says why too: the same line
    reason = next(line for line in err.splitlines() if "worker was killed by SIGKILL" in line)
    assert f"see {job['log'][0]}" in err
    assert reason in Path(job["log"][0]).read_text().splitlines()


def test_a_block_seeds_worker_killed_from_outside_says_why_in_the_blocks_log(
    server_socket, tmp_path
):
    """The log of a block of seeds (relative to the job's directory) gets the reason after its seed's header."""
    pid_file = tmp_path / "worker.pid"
    job = dict(_ping(tmp_path, sleep=60, pid_file=str(pid_file)), log=["block.log"])
    code = (
        "from bsrbench import jobserver; jobserver.run_block('bsrbench.jobserver:ping', "
        f"[{{k: v for k, v in {job!r}.items() if k in ('input', 'output')}} | {{'wildcards': {{'seed': '0'}}}}], "
        f"params={job['params']!r}, threads=1, log=['block.log'])"
    )
    client = subprocess.Popen(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env=dict(os.environ),
        stderr=subprocess.PIPE,
        text=True,
    )
    os.kill(_worker_pid(pid_file), signal.SIGKILL)
    _, err = client.communicate(timeout=60)
    assert client.returncode != 0 and "see block.log" in err
    reason = next(line for line in err.splitlines() if "worker was killed by SIGKILL" in line)
    lines = (tmp_path / "block.log").read_text().splitlines()
    assert lines[0] == "--- seed 0 ---" and lines[-1] == reason


@pytest.mark.parametrize(
    "how, words",
    [
        ("os._exit(3)", "exited with code 3"),
        ("os.kill(os.getpid(), signal.SIGTERM)", "was killed by SIGTERM"),
    ],
)
def test_exit_status_in_words(how, words):
    pid = os.fork()
    if pid == 0:
        exec(how)
        os._exit(0)
    _, status = os.waitpid(pid, 0)
    assert jobserver._describe_exit(status) == words


def test_killed_server_kills_its_worker_and_the_client_runs_the_job_itself(server_socket, tmp_path):
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))  # the server is up
    server_pid = _listening_pid(server_socket)
    pid_file = tmp_path / "worker.pid"
    job = _ping(tmp_path, sleep=5, pid_file=str(pid_file))
    (tmp_path / "out.txt").unlink()
    client = _ping_client(job, stderr=subprocess.PIPE, text=True)
    worker = _worker_pid(pid_file)
    os.kill(server_pid, signal.SIGKILL)
    _wait_gone(worker, timeout=2)  # killed with its server, long before its 5 s sleep ends
    _, err = client.communicate(timeout=60)
    assert client.returncode == 0 and "running in-process" in err
    assert (
        int((tmp_path / "out.txt").read_text()) == client.pid
    )  # written by the client, not the worker


def test_jobs_run_side_by_side_and_a_shutdown_lets_running_jobs_finish(server_socket, tmp_path):
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))  # the server is up
    clients, outs, pids = [], [], []
    for i in range(2):
        job = _ping(tmp_path, sleep=2, pid_file=str(tmp_path / f"worker{i}.pid"))
        job["output"]["path"] = str(tmp_path / f"out{i}.txt")
        code = f"from bsrbench import jobserver; jobserver.run('bsrbench.jobserver:ping', {job!r})"
        clients.append(subprocess.Popen([sys.executable, "-c", code], env=dict(os.environ)))
        outs.append(tmp_path / f"out{i}.txt")
        pids.append(tmp_path / f"worker{i}.pid")
    deadline = time.monotonic() + 60
    while not all(p.exists() for p in pids) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert all(p.exists() for p in pids) and not any(
        o.exists() for o in outs
    )  # both running at once
    assert jobserver.shutdown(server_socket) is True  # returns once the server is gone
    assert [c.wait(timeout=60) for c in clients] == [0, 0]
    assert all(o.exists() for o in outs)
    assert _server_files(server_socket) == []


def test_shutdown_stops_the_server_and_removes_its_files(server_socket, tmp_path):
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))
    name = server_socket.name
    assert _server_files(server_socket) == [name, f"{name}.lock", f"{name}.log"]
    server_pid = _listening_pid(server_socket)
    assert jobserver.shutdown(server_socket) is True
    assert _server_files(server_socket) == []
    _wait_gone(server_pid)
    assert jobserver.shutdown(server_socket) is False  # nothing to stop: a no-op


def test_server_stops_when_the_snakemake_process_it_served_is_gone(
    server_socket, tmp_path, monkeypatch
):
    """A killed Snakemake run (no onsuccess/onerror hook) still stops the server, well before the idle timeout."""
    owner = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    monkeypatch.setenv(jobserver.OWNER_VAR, str(owner.pid))
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))
    server_pid = _listening_pid(server_socket)
    time.sleep(1.5)
    name = server_socket.name
    assert _server_files(server_socket) == [
        name,
        f"{name}.lock",
        f"{name}.log",
    ]  # owner alive: serving
    owner.kill()
    owner.wait()
    _wait_gone(server_pid, timeout=10)
    assert _server_files(server_socket) == []


def test_shutdown_removes_what_a_killed_server_left(server_socket, tmp_path):
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))
    server_pid = _listening_pid(server_socket)
    os.kill(server_pid, signal.SIGKILL)
    _wait_gone(server_pid)
    assert server_socket.name in _server_files(server_socket)
    assert jobserver.shutdown(server_socket) is False
    assert _server_files(server_socket) == []


def _listening_pid(path):
    """The pid of the process listening on the Unix socket ``path`` (from /proc/net/unix and /proc/*/fd). The job
    server binds its socket by name inside its working directory (the checked directory), so /proc/net/unix
    shows that name; the process's working directory tells which server it is."""
    inodes = {  # the listening socket (flag __SO_ACCEPTCON), not a connection accepted on it
        ln.split()[6]: ln.split()[7]
        for ln in open("/proc/net/unix")
        if len(ln.split()) > 7
        and ln.split()[3] == "00010000"
        and ln.split()[7] in (str(path), path.name)
    }
    for fd_dir in Path("/proc").glob("[0-9]*/fd"):
        try:
            held = {os.readlink(fd) for fd in fd_dir.iterdir()}
            for inode, name in inodes.items():
                if f"socket:[{inode}]" in held and (
                    name == str(path) or os.readlink(fd_dir.parent / "cwd") == str(path.parent)
                ):
                    return int(fd_dir.parent.name)
        except OSError:
            continue
    raise AssertionError(f"no process listens on {path}")


def _wait_gone(pid, timeout=30):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
            with open(f"/proc/{pid}/stat") as f:
                if f.read().split()[2] == "Z":  # exited, not yet reaped by its parent
                    return
        except (ProcessLookupError, FileNotFoundError):
            return
        time.sleep(0.05)
    pytest.fail(f"process {pid} still alive after {timeout} s")
    pytest.fail(f"process {pid} still alive")


def test_shell_job_command_through_server_and_in_process(server_socket, tmp_path):
    """`python -m bsrbench.jobserver job TARGET --threads --log JSON` (the rules' shell command, with the JSON of
    job_params) runs the job with its params, wildcards and log, in the server or, with the server switched off
    by the environment variable, in the command's own process."""
    params = {"estimator": "x:Y", "n": 3, "per_method": lambda w: f"{w['method']}!"}

    class Wildcards(dict):  # job_params calls params functions with Snakemake's wildcards object
        def __getattr__(self, key):
            return self[key]

    wildcards = Wildcards(method="PM")
    job_json = jobserver.job_params()(
        wildcards,
        {"features": "f.npz", "code": ["a.py", "b.py"]},
        {"path": str(tmp_path / "out.txt")},
    )
    settings = jobserver.job_settings(params)(wildcards)
    job = json.loads(job_json)
    assert json.loads(settings) == {"estimator": "x:Y", "n": 3, "per_method": "PM!"}
    assert job["input"] == {"features": "f.npz", "code": ["a.py", "b.py"]}
    assert job["wildcards"] == {"method": "PM"} and "params" not in job
    for use in ("1", "0"):
        log = tmp_path / f"job{use}.log"
        (tmp_path / "out.txt").unlink(missing_ok=True)
        env = dict(os.environ, **{jobserver.USE_SERVER_VAR: use})
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "bsrbench.jobserver",
                "job",
                "bsrbench.jobserver:ping",
                "--threads",
                "1",
                "--log",
                str(log),
                job_json,
                "--settings",
                settings,
            ],
            env=env,
            cwd=tmp_path,
        )
        assert proc.wait(timeout=120) == 0
        worker = int((tmp_path / "out.txt").read_text())
        # through the server the job runs in a fork of the server; switched off, in the command's own process
        assert (worker != proc.pid) if use == "1" else (worker == proc.pid)
        assert "ping from pid" in log.read_text()
    # a failing job: non-zero exit, the traceback in the job's log
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "bsrbench.jobserver",
            "job",
            "bsrbench.jobserver:no_such_job",
            "--log",
            str(tmp_path / "bad.log"),
            job_json,
        ],
        env=dict(os.environ),
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert bad.returncode != 0
    assert "no_such_job" in (tmp_path / "bad.log").read_text()


@pytest.mark.parametrize("args, code", [(["--help"], 0), ([], 2), (["-s", "a"], 2)])
def test_command_line_without_a_socket_prints_usage(tmp_path, args, code):
    """`python -m bsrbench.jobserver --help` (or no argument) prints the usage; it used to start a server on a
    socket named '--help' (or fail with an IndexError)."""
    out = subprocess.run(
        [sys.executable, "-m", "bsrbench.jobserver", *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == code and "usage: python -m bsrbench.jobserver SOCKET" in out.stderr
    assert list(tmp_path.iterdir()) == []


def test_preload_imports_the_job_module_and_runs_the_warm_ups(tmp_path, monkeypatch):
    """The server preloads a job module and the modules of its PRELOAD, and runs the warm_up() of each that has
    one; a failing warm-up or a missing module is printed, not raised (it only costs the jobs time)."""
    (tmp_path / "jobs_x.py").write_text(
        "PRELOAD = ('model_x', 'model_bad', 'no_such_module_x')\n"
        "def warm_up():\n    open('jobs.warm', 'w').write('1')\n"
    )
    (tmp_path / "model_x.py").write_text("def warm_up():\n    open('model.warm', 'w').write('1')\n")
    (tmp_path / "model_bad.py").write_text("def warm_up():\n    raise RuntimeError('boom')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    jobserver._preload(["jobs_x", "also_missing_x"])
    assert (tmp_path / "jobs.warm").is_file() and (tmp_path / "model.warm").is_file()


#: Run in a fresh interpreter: preload as a job server does, then run a small job of every configured method (fit
#: with split conformal, and for PM and Ridge a CV, for PM two chains pooled) and print the modules the jobs imported.
_JOBS_AFTER_PRELOAD = """
import json, sys
from bsrbench import jobserver
jobserver._preload(["bsrbench.jobs"])
before = set(sys.modules)
from bsrbench.io import load_features
from bsrbench.methods import configured
from bsrbench.runs import cross_validate, pool_chains, run_chain, run_job
from bsrbench.splits import JobSpec
feats = load_features(sys.argv[1])
small = {"PM": {"n_atoms": 4, "n_neighbors": 2, "n_iter": 8, "n_burn_in": 4, "thin": 2},
         "RF": {"n_estimators": 3}, "MLP": {"hidden_units": 4}}
for name, m in configured().items():
    spec, params = JobSpec("syn", "act", name, 60, 0, min_test=30), small.get(name, {})
    run_job(spec, feats, estimator=m.estimator, params=params, conformal={"level": 0.9, "params": {}})
    if name in ("PM", "Ridge"):
        grid = {"n_neighbors": [1, 2]} if name == "PM" else {"alpha": [0.1, 1.0]}
        cross_validate(spec, feats, estimator=m.estimator, params=params, grid=grid, folds=2)
    if name == "PM":
        chains = [run_chain(spec, feats, estimator=m.estimator, params=params, chain=c) for c in (0, 1)]
        pool_chains(spec, feats, chains, estimator=m.estimator, params=params)
print(json.dumps(sorted(set(sys.modules) - before)))
"""
#: Modules that packages import lazily inside their own functions, which no import statement of ours names.
_LAZY_INSIDE_PACKAGES = {"pandas.core.methods.to_dict"}  # DataFrame.to_dict (the CV table)


def test_the_derived_preload_holds_every_module_a_job_of_each_method_imports(
    tmp_path, synthetic_features
):
    """After the server's preload (jobs.PRELOAD, derived from the import graph), the jobs of every configured
    method import no module of another package: e.g. scoringrules (the CRPS; its import compiles numba
    functions for seconds) and ArviZ (R-hat of pooled chains) are loaded once, in the server."""
    from bsrbench import jobs

    preload = jobs.PRELOAD
    assert {"scoringrules", "arviz", "sklearn.gaussian_process", "bsrbench.runs"} <= set(preload)
    assert "bsrbench.reporting" not in preload  # only what the jobs import
    out = subprocess.run(
        [sys.executable, "-c", _JOBS_AFTER_PRELOAD, str(synthetic_features(tmp_path, n=120))],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr
    new = json.loads(out.stdout.strip().splitlines()[-1])
    foreign = {
        m
        for m in new
        if m.partition(".")[0] not in sys.stdlib_module_names and not m.startswith("bsrbench")
    }
    assert foreign <= _LAZY_INSIDE_PACKAGES, sorted(foreign - _LAZY_INSIDE_PACKAGES)


# ------------------------------------------------------------------------------ only this user (issue 33)
def _nobody():
    """uid and gid of the user ``nobody``; the test is skipped unless it runs as root (as in CI)."""
    import pwd

    if os.geteuid() != 0:
        pytest.skip("acting as another user needs root")
    try:
        pw = pwd.getpwnam("nobody")
    except KeyError:
        pytest.skip("no user nobody")
    return pw.pw_uid, pw.pw_gid


class _Payload:
    """Unpickling this runs code: it creates the file ``marker``."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return exec, (f"open({self.marker!r}, 'w').write('payload ran')",)


def _pickle_message(marker):
    """A message in the server's former framing (length, pickle) whose unpickling creates ``marker``."""
    data = pickle.dumps(_Payload(marker))
    return struct.pack("!Q", len(data)) + data


def _run_client(tmp_path, timeout=120):
    """Run a ping job as the study's jobs do, in a fresh process: (its exit code, its pid, its stderr)."""
    job = _ping(tmp_path)
    code = f"from bsrbench import jobserver; jobserver.run('bsrbench.jobserver:ping', {job!r})"
    proc = subprocess.Popen(
        [sys.executable, "-c", code], env=dict(os.environ), stderr=subprocess.PIPE, text=True
    )
    _, err = proc.communicate(timeout=timeout)  # it must never hang
    return proc.returncode, proc.pid, err


#: A server that binds ``path`` (as root, in the private directory), becomes user ``uid`` before it listens (the
#: kernel records the listener's credentials at listen()), and answers every connection with ``reply``.
FAKE_SERVER = """
import os, socket, sys
path, uid, gid, reply = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), bytes.fromhex(sys.argv[4])
srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
srv.bind(path)
if uid != os.geteuid():
    os.setgroups([])
    os.setgid(gid)
    os.setuid(uid)
srv.listen(8)
print("listening", flush=True)
while True:
    conn, _ = srv.accept()
    conn.settimeout(5)
    try:
        conn.recv(1 << 16)  # the client's request, if it sends one
        conn.sendall(reply)
    except OSError:
        pass
    conn.close()
"""


@contextmanager
def _fake_server(path, uid, gid, reply):
    proc = subprocess.Popen(
        [sys.executable, "-c", FAKE_SERVER, str(path), str(uid), str(gid), reply.hex()],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout.readline() == "listening\n"
        yield proc
    finally:
        proc.kill()
        proc.wait()


def test_a_server_of_another_user_is_refused_and_its_reply_never_loaded(server_socket, tmp_path):
    """Another user's process listening where the jobs connect (here placed past the directory check, which
    another test covers): the job does not talk to it, runs in-process with one line why, and the reply, which
    would run code if unpickled (as it did before), is never read."""
    uid, gid = _nobody()
    marker = tmp_path / "payload-ran"
    with _fake_server(server_socket, uid, gid, _pickle_message(marker)) as fake:
        code, pid, err = _run_client(tmp_path)
        assert (
            _listening_pid(server_socket) == fake.pid
        )  # still its socket: the job started no server
    expected = (
        f"bsrbench.jobserver: refused the server at {server_socket}: it runs as uid {uid}, not as this user "
        f"(uid {os.geteuid()}); running in-process"
    )
    assert (
        not marker.exists()
    )  # before issue 33's fix, it existed and the job failed with a TypeError
    assert code == 0 and expected in err.splitlines(), err
    assert int((tmp_path / "out.txt").read_text()) == pid  # the job ran in the client's own process
    assert "ping from pid" in (tmp_path / "ping.log").read_text()


def test_a_pickled_reply_is_never_loaded_even_from_this_user(server_socket, tmp_path):
    """Requests and replies are JSON: a server of the same user that answers with a pickle makes the job run
    in-process, and the pickle runs nothing."""
    marker = tmp_path / "payload-ran"
    with _fake_server(server_socket, os.geteuid(), os.getegid(), _pickle_message(marker)):
        code, pid, err = _run_client(tmp_path)
    assert not marker.exists()
    assert code == 0 and "(a message that is not JSON); running in-process" in err, err
    assert int((tmp_path / "out.txt").read_text()) == pid


def test_the_server_never_loads_a_pickled_request(server_socket, tmp_path):
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))  # the server is up
    server_pid = _listening_pid(server_socket)
    marker = tmp_path / "payload-ran"
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.connect(str(server_socket))
        s.sendall(_pickle_message(marker))
        # answered with one line why, then closed
        reply = jobserver._recv(s)
        assert reply == {
            "status": "error",
            "detail": "refused a request: a message that is not JSON",
        }
        assert s.recv(1 << 16) == b""
    assert not marker.exists()
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))  # and it serves on
    assert _listening_pid(server_socket) == server_pid
    assert int((tmp_path / "out.txt").read_text()) != os.getpid()


#: A client that becomes user ``uid`` before it connects (the kernel records its credentials at connect()),
#: connects twice to ``path``: once sending nothing, once sending ``request``; prints what it saw each time.
FOREIGN_CLIENT = """
import os, socket, sys
path, uid, gid, request = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), bytes.fromhex(sys.argv[4])
os.setgroups([])
os.setgid(gid)
os.setuid(uid)
for data in (b"", request):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.connect(path)
    try:
        if data:
            s.sendall(data)
        print(repr(s.recv(1 << 16)))
    except OSError as exc:
        print(type(exc).__name__)
    s.close()
"""


def _job_request(tmp_path, output):
    """The bytes of a valid job request for the server at hand: a ping job writing ``output``."""
    job = dict(_ping(tmp_path), output={"path": str(output)})
    request = {
        "target": "bsrbench.jobserver:ping",
        "job": job,
        "fingerprint": jobserver.fingerprint(),
        "cwd": str(tmp_path),
        "owner": None,
    }
    a, b = socket.socketpair()
    with a, b:
        jobserver._send(a, request)
        a.shutdown(socket.SHUT_WR)
        return b"".join(iter(lambda: b.recv(1 << 16), b""))


def test_a_client_of_another_user_is_refused_unread(server_socket, tmp_path):
    """Another user's process that reaches the socket (here through a hard link in a directory it may enter: the
    private directory would stop it, which another test covers) gets its connection closed unread, and its
    job, which the server runs for this user, does not run."""
    uid, gid = _nobody()
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))  # the server is up
    server_pid = _listening_pid(server_socket)
    ours, theirs = tmp_path / "ours.txt", tmp_path / "theirs.txt"
    with socket.socket(
        socket.AF_UNIX, socket.SOCK_STREAM
    ) as s:  # the request is valid: for us it runs
        s.connect(str(server_socket))
        s.sendall(_job_request(tmp_path, ours))
        assert jobserver._recv(s) == {"status": "ok", "detail": None} and ours.exists()
    with tempfile.TemporaryDirectory() as open_dir:
        os.chmod(open_dir, 0o711)
        link = Path(open_dir) / "s.sock"
        os.link(server_socket, link)
        os.chmod(link, 0o777)  # connecting needs write permission on the socket
        out = subprocess.run(
            [sys.executable, "-c", FOREIGN_CLIENT, str(link), str(uid), str(gid)]
            + [_job_request(tmp_path, theirs).hex()],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert out.returncode == 0, out.stderr
    # without sending: EOF; after sending: the kernel's ECONNRESET (closed with its bytes unread) or EPIPE
    # (closed before it sent)
    nothing_sent, request_sent = out.stdout.splitlines()
    assert nothing_sent == "b''" and request_sent in ("ConnectionResetError", "BrokenPipeError")
    assert not theirs.exists()
    refusal = f"bsrbench.jobserver: refused a client of uid {uid} (this server runs as uid {os.geteuid()})"
    assert Path(f"{server_socket}.log").read_text().splitlines() == [refusal, refusal]
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))  # the server serves its own user on
    assert _listening_pid(server_socket) == server_pid
    assert int((tmp_path / "out.txt").read_text()) != os.getpid()


@pytest.mark.parametrize("umask", [0o022, 0o000, 0o777])
def test_the_private_directory_is_made_for_this_user_only(
    runtime_base, tmp_path, monkeypatch, umask
):
    """$XDG_RUNTIME_DIR/bsrbench, else $TMPDIR/bsrbench-<uid>, mode 0700 whatever the umask."""
    old = os.umask(umask)
    try:
        made = [jobserver.runtime_dir()]
        monkeypatch.delenv("XDG_RUNTIME_DIR")
        monkeypatch.setenv("TMPDIR", str(tmp_path))
        made.append(jobserver.runtime_dir())
    finally:
        os.umask(old)
    assert made == [runtime_base / "bsrbench", tmp_path / f"bsrbench-{os.geteuid()}"]
    for path in made:
        st = path.lstat()
        assert stat.S_ISDIR(st.st_mode) and stat.S_IMODE(st.st_mode) == 0o700
        assert st.st_uid == os.geteuid()
    assert jobserver.socket_path().parent == made[1]
    assert jobserver.runtime_dir() == made[1]  # an existing private directory is used as it is


def _unsafe(path, how):
    """Put at ``path`` what ``how`` names; the kind, uid and mode the refusal should report."""
    me = os.geteuid()
    if how == "open to others":
        path.mkdir()
        path.chmod(0o755)
        return "a directory", me, "0755"
    if how == "open to the group":
        path.mkdir()
        path.chmod(0o710)
        return "a directory", me, "0710"
    if how == "owned by another user":
        uid, gid = _nobody()
        path.mkdir(mode=0o700)
        os.chown(path, uid, gid)
        return "a directory", uid, "0700"
    if how == "a symbolic link":
        (path.parent / "elsewhere").mkdir(mode=0o700)
        path.symlink_to(path.parent / "elsewhere")
        return "a symbolic link", me, "0777"
    path.write_text("")
    path.chmod(0o600)
    return "a file", me, "0600"


@pytest.mark.parametrize(
    "how",
    ["open to others", "open to the group", "owned by another user", "a symbolic link", "a file"],
)
def test_an_unsafe_directory_is_refused_with_what_was_found_and_expected(
    runtime_base, tmp_path, monkeypatch, capsys, how
):
    path = runtime_base / "bsrbench"
    kind, uid, mode = _unsafe(path, how)
    message = (
        f"unsafe job server directory {path}: {kind} owned by uid {uid} with mode {mode}; expected a directory "
        f"owned by uid {os.geteuid()} (this user) with mode 0700 (no access for group or others)"
    )
    with pytest.raises(jobserver.UnsafeDirectory, match=f"^{re.escape(message)}$"):
        jobserver.socket_path()
    # a job runs in-process, with that line; the run's end (Snakefile's handlers) stops nothing and raises nothing
    monkeypatch.setattr(sys, "stderr", sys.stderr)  # run_local points stderr at the job's log
    jobserver.run("bsrbench.jobserver:ping", _ping(tmp_path))
    assert int((tmp_path / "out.txt").read_text()) == os.getpid()
    assert jobserver.shutdown() is False
    err = capsys.readouterr().err
    assert f"bsrbench.jobserver: {message}; running in-process" in err.splitlines(), err
    assert list(path.parent.glob("**/*.sock")) == []  # nothing was put in the unsafe place


def test_a_block_job_runs_the_job_of_each_seed_in_turn_and_names_a_failing_seed(
    server_socket, tmp_path
):
    """The JSON of block_job_params holds each seed's job spec (its wildcards, its files of the block's output
    lists, its per-seed inputs); the command runs them one after the other into the block's log, through the
    server (a fork per seed) or in its own process; a failing seed stops the block with its name."""

    class Wildcards(dict):
        def __getattr__(self, key):
            return self[key]

    outs = [str(tmp_path / "out3.txt"), str(tmp_path / "missing" / "out4.txt")]
    params = jobserver.block_job_params([3, 4], {"cv": lambda w: f"cv{w.seed}.json"})
    job = json.loads(params(Wildcards(method="PM"), {"code": ["a.py"], "cv": []}, {"path": outs}))
    assert job["block"] == [
        {
            "input": {"cv": f"cv{s}.json"},  # no code paths: no job reads them
            "output": {"path": out},
            "wildcards": {"method": "PM", "seed": str(s)},
        }
        for s, out in zip((3, 4), outs)
    ]

    def command(use, log):
        return subprocess.run(
            [sys.executable, "-m", "bsrbench.jobserver", "job", "bsrbench.jobserver:ping",
             "--threads", "1", "--log", str(log), json.dumps(job), "--settings", "{}"],
            env=dict(os.environ, **{jobserver.USE_SERVER_VAR: use}), cwd=tmp_path,
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip

    for use in ("1", "0"):
        (tmp_path / "out3.txt").unlink(missing_ok=True)
        log = tmp_path / f"block{use}.log"
        # seed 4's output folder is missing: seed 3 runs, seed 4 fails
        bad = command(use, log)
        assert bad.returncode != 0
        assert "bsrbench.jobserver:ping: seed 4 of the block of seeds 3-4 failed" in bad.stderr
        assert "FileNotFoundError" in bad.stderr + log.read_text()
        assert (tmp_path / "out3.txt").exists()
        (tmp_path / "missing").mkdir(exist_ok=True)
        res = command(use, log)
        assert res.returncode == 0, res.stderr
        pids = {int(Path(p).read_text()) for p in outs}
        text = log.read_text()
        assert text.index("--- seed 3 ---") < text.index("--- seed 4 ---")
        assert (
            text.count("ping from pid") == 2 and "FileNotFoundError" not in text
        )  # the log emptied
        # through the server one fork per seed; switched off, both in the command's own process
        assert len(pids) == (2 if use == "1" else 1)
        (tmp_path / "missing" / "out4.txt").unlink()
        (tmp_path / "missing").rmdir()
    # the commands' server (one per working directory: tmp_path's, not the fixture's)
    assert jobserver.shutdown(jobserver.socket_path(cwd=tmp_path))


def test_a_chains_job_runs_each_chain_in_turn_and_names_a_failing_chain(tmp_path):
    """The JSON of chains_job_params: C chain steps (the job's inputs but code, chain file c, wildcard chain); the
    command runs them one after the other into the job's log and names a failing chain."""

    class Wildcards(dict):
        def __getattr__(self, key):
            return self[key]

    outs = [str(tmp_path / "chain0.txt"), str(tmp_path / "missing" / "chain1.txt")]
    params = jobserver.chains_job_params(2)
    inputs = {"features": "f.npz", "cv": [], "code": ["a.py"]}
    job = json.loads(params(Wildcards(method="PM", seed="7"), inputs, {"chains": outs}))
    assert job["block"] == [
        {
            "input": {"features": "f.npz", "cv": []},
            "output": {"chain": out},
            "wildcards": {"method": "PM", "seed": "7", "chain": str(c)},
        }
        for c, out in enumerate(outs)
    ]
    # ping writes output "path": the same steps with that name
    for step in job["block"]:
        step["output"] = {"path": step["output"]["chain"]}
    log = tmp_path / "chains.log"
    res = subprocess.run(
        [sys.executable, "-m", "bsrbench.jobserver", "job", "bsrbench.jobserver:ping",
         "--threads", "1", "--log", str(log), json.dumps(job), "--settings", "{}"],
        env=dict(os.environ, **{jobserver.USE_SERVER_VAR: "0"}), cwd=tmp_path,
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert res.returncode != 0
    assert "bsrbench.jobserver:ping: seed 7 chain 1 of the chains of seed 7 failed" in res.stderr, (
        res.stderr
    )
    assert "FileNotFoundError" in res.stderr + log.read_text()
    assert (tmp_path / "chain0.txt").exists()
    text = log.read_text()
    assert text.index("--- seed 7 chain 0 ---") < text.index("--- seed 7 chain 1 ---")
