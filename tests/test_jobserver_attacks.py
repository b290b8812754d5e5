"""The job server against a same-user client that sends what it likes, and against other users who can write
where its files live: only the study's job functions run, malformed or slow requests get one line why and hold
up no other job, a server that does not answer makes the job run in-process, and nothing is bound or written
through a swapped directory or a planted link."""

import json
import os
import re
import reprlib
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest
import test_jobserver
from test_jobserver import _listening_pid, _ping, _run_client, _server_files, _wait_gone

from bsrbench import jobserver

ROOT = Path(__file__).resolve().parents[1]
PING = "bsrbench.jobserver:ping"
# the fixtures of the job server's tests: a private runtime directory, a server's socket in it
runtime_base = test_jobserver.runtime_base
server_socket = test_jobserver.server_socket
#: The job functions the server runs, as its refusals list them.
ALLOWED = (
    "bsrbench.jobs:cv, bsrbench.jobs:fit, bsrbench.jobs:fit_chain, bsrbench.jobs:pool, "
    "bsrbench.jobserver:ping"
)


def _frame(message):
    """``message`` (bytes, or plain data as JSON) as the protocol frames it: its length (8 bytes), then it."""
    data = message if isinstance(message, bytes) else json.dumps(message).encode()
    return struct.pack("!Q", len(data)) + data


def _request(tmp_path, output, **job_fields):
    """A valid request for a ping job writing ``output``, its job spec updated with ``job_fields``."""
    job = dict(_ping(tmp_path), output={"path": str(output)}, **job_fields)
    return {
        "target": PING,
        "job": job,
        "fingerprint": jobserver.fingerprint(),
        "cwd": str(tmp_path),
        "owner": None,
    }


def _ask(path, data, timeout=30):
    """Send the bytes ``data`` to the server at ``path``; its reply (EOFError if it closes without one)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(timeout)
        s.connect(str(path))
        s.sendall(data)
        return jobserver._recv(s)


def _serves_on(path, server_pid, tmp_path):
    """The server at ``path`` is still ``server_pid`` and runs a job in a worker."""
    (tmp_path / "out.txt").unlink(missing_ok=True)
    jobserver.run(PING, _ping(tmp_path))
    assert int((tmp_path / "out.txt").read_text()) != os.getpid()
    assert _listening_pid(path) == server_pid


def _up(path, tmp_path):
    """Start the server at ``path`` with a ping job; its pid."""
    jobserver.run(PING, _ping(tmp_path))
    return _listening_pid(path)


# ----------------------------------------------------------------------------- only the study's job functions
def test_a_job_target_off_the_list_is_refused_by_the_server_and_its_payload_never_runs(
    server_socket, tmp_path
):
    """``subprocess:run`` on a job spec {"touch": 0, MARKER: 0} would run ``touch MARKER`` (Popen takes the dict's
    keys as the command): it ran before the allow-list."""
    server_pid = _up(server_socket, tmp_path)
    marker = tmp_path / "payload-ran"
    request = dict(_request(tmp_path, tmp_path / "x"), target="subprocess:run")
    request["job"] = {"touch": 0, str(marker): 0}
    reply = _ask(server_socket, _frame(request))
    detail = f"refused a request: job target 'subprocess:run' is not one of the study's job functions ({ALLOWED})"
    assert reply == {"status": "error", "detail": detail}
    time.sleep(1)  # time for a worker, had one been forked
    assert not marker.exists()
    _serves_on(server_socket, server_pid, tmp_path)


def test_a_job_target_off_the_list_is_refused_by_the_client(server_socket, tmp_path):
    """The client refuses it with the same check, before it asks a server or runs anything: run, run_block,
    run_local and the rules' command line."""
    marker = tmp_path / "payload-ran"
    job = {"touch": 0, str(marker): 0}
    line = f"bsrbench.jobserver: refused: job target 'subprocess:run' is not one of the study's job functions ({ALLOWED})"
    with pytest.raises(SystemExit) as exc:
        jobserver.run("subprocess:run", job)
    assert str(exc.value) == line
    log = tmp_path / "block.log"
    with pytest.raises(SystemExit) as exc:
        jobserver.run_block(
            "subprocess:run",
            [{"input": {}, "output": {}, "wildcards": {"seed": "0"}}],
            params={},
            threads=1,
            log=[str(log)],
        )
    assert str(exc.value) == line and log.read_text().splitlines() == [line]
    with pytest.raises(jobserver.JobRefused):
        jobserver.run_local("subprocess:run", job)
    log = tmp_path / "job.log"
    out = subprocess.run(
        [sys.executable, "-m", "bsrbench.jobserver", "job", "os:system", "{}", "--log", str(log)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    refusal = line.replace("'subprocess:run'", "'os:system'")
    assert out.returncode == 1 and out.stderr.splitlines() == [refusal], out.stderr
    assert log.read_text().splitlines() == [refusal]
    assert not marker.exists()
    assert not server_socket.exists()  # no server was even asked


def test_the_allowed_targets_are_those_the_workflow_and_the_benchmarks_name():
    """The allow-list is what the rules' shell commands and benchmarks/bench_job_floor.py run, nothing more."""
    rules = "".join(p.read_text() for p in (ROOT / "workflow" / "rules").glob("*.smk"))
    bench = (ROOT / "benchmarks" / "bench_job_floor.py").read_text()
    named = set(re.findall(r'target="([^"]+)"', rules)) | set(
        re.findall(r'\["(bsrbench\.[\w.]+:\w+)",', bench)
    )
    assert named == set(jobserver.JOB_TARGETS)
    for target in jobserver.JOB_TARGETS:
        assert callable(jobserver.job_function(target))


# ------------------------------------------------------------------------------------------------- frames
def test_nesting_is_bounded_before_the_parser_recurses():
    """32 levels pass, 33 do not; brackets inside strings (with escaped quotes) do not count."""
    ok = "[" * 32 + "]" * 32
    assert jobserver._decode(ok.encode()) == json.loads(ok)
    for bad in ("[" * 33 + "]" * 33, "[" * 200_000, "{" * 40 + "]" * 40):
        with pytest.raises(jobserver.ProtocolError, match="nested more than 32 deep, or not JSON"):
            jobserver._decode(bad.encode())
    text = json.dumps({"a": ['x"[[[[\\' + "[" * 100, "{" * 100]})
    assert jobserver._decode(text.encode()) == json.loads(text)


def test_a_deeply_nested_frame_gets_an_error_and_the_server_serves_on(server_socket, tmp_path):
    """``[`` x 200000 made json.loads raise a RecursionError that ended the server."""
    server_pid = _up(server_socket, tmp_path)
    reply = _ask(server_socket, _frame(b"[" * 200_000))
    assert reply == {
        "status": "error",
        "detail": "refused a request: a message nested more than 32 deep, or not JSON",
    }
    _serves_on(server_socket, server_pid, tmp_path)


def _peak_rss_kb(pid):
    status = Path(f"/proc/{pid}/status").read_text()
    return int(re.search(r"VmHWM:\s+(\d+) kB", status).group(1))


def test_an_oversized_frame_is_refused_before_its_body_is_read(server_socket, tmp_path):
    """A 16 MiB frame was read whole (and left the server at hundreds of MB); now its announced length is
    refused at once, and the server's peak memory does not grow by its size."""
    server_pid = _up(server_socket, tmp_path)
    detail = (
        "refused a request: a message of 16777216 bytes announced, more than the limit of 4194304"
    )
    peak = _peak_rss_kb(server_pid)
    assert _ask(server_socket, struct.pack("!Q", 16 << 20)) == {"status": "error", "detail": detail}
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(30)
        s.connect(str(server_socket))
        try:
            s.sendall(struct.pack("!Q", 16 << 20) + b" " * (16 << 20))
        except OSError:
            pass  # the server closed the connection after the length
    assert _peak_rss_kb(server_pid) - peak < 8 * 1024
    _serves_on(server_socket, server_pid, tmp_path)


def test_a_reply_over_the_frame_limit_is_refused_by_the_client(server_socket, tmp_path):
    """The client's reading is bounded the same way (no server involved: a socket pair)."""
    a, b = socket.socketpair()
    with a, b:
        a.sendall(struct.pack("!Q", (4 << 20) + 1))
        with pytest.raises(jobserver.ProtocolError, match="4194305 bytes announced"):
            jobserver._recv(b, time.monotonic() + 10)


#: (what a request has instead of a valid field, the server's reply detail)
MALFORMED = [
    (
        {"owner": 2**70},
        "owner is 1180591620717411303424; expected a process id (1 to 4194304) or null",
    ),
    ({"owner": True}, "owner is True; expected a process id (1 to 4194304) or null"),
    ({"cwd": "relative/dir"}, "cwd is 'relative/dir'; expected an absolute path"),
    ({"ack": "yes"}, "ack is 'yes'; expected true or false"),
    (
        {"target": "x" * 300},
        f"target is {reprlib.repr('x' * 300)}; expected a string of at most 200 characters",
    ),
    (
        {"extra": 1},
        "a request with fields ['cwd', 'extra', 'fingerprint', 'job', 'owner', 'target']; expected target, "
        "job, fingerprint, cwd and optionally owner, ack",
    ),
    ({"job": {"threads": 0}}, "job field threads is 0; expected 1 to 1024"),
    ({"job": {"threads": 10**6}}, "job field threads is 1000000; expected 1 to 1024"),
    ({"job": {"threads": "2"}}, "job field threads is '2'; expected an integer"),
    ({"job": {"log": "x.log"}}, "job field log is 'x.log'; expected a list"),
    (
        {"job": {"log": ["a\0b"]}},
        "job field log is ['a\\x00b']; expected a list of at most 8 paths",
    ),
    (
        {"job": {"code": []}},
        "job field 'code' unknown; expected input, output, params, wildcards, log, log_append, threads",
    ),
    (
        {"job": {"params": {"s": "x" * 70_000}}},
        "a string of 70000 characters in the job, more than 65536",
    ),
    (
        {"job": {"params": {"n": 2**70}}},
        "an integer in the job outside 64 bits: 1180591620717411303424",
    ),
]


def test_every_field_is_checked_and_a_malformed_request_gets_one_line_why(server_socket, tmp_path):
    """An owner of 2**70 ran its job and then ended the server with an OverflowError (os.kill in the owner
    check); now it is refused like every field of the wrong type or range, no job runs, and the server serves
    on (also after a second of its idle checks)."""
    server_pid = _up(server_socket, tmp_path)
    output = tmp_path / "ran.txt"
    for change, why in MALFORMED:
        request = _request(tmp_path, output)
        for key, value in change.items():
            if key == "job":
                request["job"].update(value)
            else:
                request[key] = value
        reply = _ask(server_socket, _frame(request))
        assert reply == {"status": "error", "detail": f"refused a request: {why}"}, change
    time.sleep(2)  # the server's loop checks the owners it knows about every second
    assert not output.exists()
    _serves_on(server_socket, server_pid, tmp_path)


# ---------------------------------------------------------------------------------------------- deadlines
def test_a_silent_client_does_not_hold_up_the_next_job(server_socket, tmp_path, monkeypatch):
    """A client that connects and sends nothing held the server for 10 s (a timeout per recv) before the next job
    ran; now the server reads requests as they come, so the next job runs while the silent client's deadline (60
    s here) still runs."""
    monkeypatch.setenv(jobserver.REQUEST_TIMEOUT_VAR, "60")
    server_pid = _up(server_socket, tmp_path)
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as silent:
        silent.connect(str(server_socket))
        _serves_on(server_socket, server_pid, tmp_path)
        silent.setblocking(False)
        with pytest.raises(BlockingIOError):  # still open: the job did not wait for it to be closed
            silent.recv(1)


def test_a_slow_client_is_cut_off_at_its_request_deadline(server_socket, tmp_path, monkeypatch):
    """A client sending a byte at a time (every 0.2 s) held the server as long as it liked (the timeout was per
    recv); now its whole request has a deadline (1 s here), it gets one line why, and other jobs run meanwhile."""
    monkeypatch.setenv(jobserver.REQUEST_TIMEOUT_VAR, "1")
    server_pid = _up(server_socket, tmp_path)
    output = tmp_path / "slow.txt"
    data = _frame(_request(tmp_path, output))
    stop = threading.Event()
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as slow:
        slow.connect(str(server_socket))

        def trickle():
            for byte in data:
                if stop.wait(0.2):
                    return
                try:
                    slow.send(bytes([byte]))
                except OSError:
                    return

        sender = threading.Thread(target=trickle)
        sender.start()
        try:
            _serves_on(server_socket, server_pid, tmp_path)
            slow.settimeout(20)
            reply = jobserver._recv(slow)
        finally:
            stop.set()
            sender.join()
    assert reply == {
        "status": "error",
        "detail": "refused a request: not complete within 1 s",
    }
    assert not output.exists()
    _serves_on(server_socket, server_pid, tmp_path)


def test_an_unread_large_error_reply_does_not_hold_up_the_next_job(server_socket, tmp_path):
    """A failing job's 3 MB error message, relayed to a client that never reads it, blocked the server in
    sendall, and every later job with it (the client had no timeout either). Now the message is cut to 64 KiB
    (the job's log has all of it) and replies are written without blocking."""
    server_pid = _up(server_socket, tmp_path)
    request = _request(tmp_path, tmp_path / "big.txt", params={"fail": ["x" * 60_000] * 50})
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as unread:
        unread.connect(str(server_socket))
        unread.sendall(_frame(request))
        code, pid, err = _run_client(tmp_path, timeout=120)  # the next job, in a client of its own
        assert code == 0, err
        assert int((tmp_path / "out.txt").read_text()) != pid  # run by the server
        assert _listening_pid(server_socket) == server_pid
        unread.settimeout(30)
        reply = jobserver._recv(unread)
    assert reply["status"] == "error" and len(reply["detail"]) < 70_000
    assert "ValueError: ping asked to fail" in reply["detail"]
    assert "characters cut: the job's log has them" in reply["detail"]
    assert (tmp_path / "ping.log").stat().st_size > 3_000_000  # all of it


#: A same-user server that reads each request and then answers ``reply`` (a JSON template: SERVER_PID is its
#: pid; empty: nothing) and never anything more, keeping the connection open.
MUTE_SERVER = """
import os, socket, struct, sys
path, reply = sys.argv[1], sys.argv[2].replace("SERVER_PID", str(os.getpid())).encode()
srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
srv.bind(path)
srv.listen(8)
print("listening", flush=True)
held = []
while True:
    conn, _ = srv.accept()
    held.append(conn)
    try:
        (n,) = struct.unpack("!Q", conn.recv(8, socket.MSG_WAITALL))
        conn.recv(n, socket.MSG_WAITALL)
        if reply:
            conn.sendall(struct.pack("!Q", len(reply)) + reply)
    except OSError:
        pass
"""


def _mute_server(path, reply=""):
    proc = subprocess.Popen(
        [sys.executable, "-c", MUTE_SERVER, str(path), reply], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline() == "listening\n"
    return proc


def test_a_server_that_never_answers_makes_the_job_run_in_process(
    server_socket, tmp_path, monkeypatch
):
    """The client waited forever for a server that takes the request and says nothing; now it gives the server
    BSRBENCH_JOBSERVER_TIMEOUT seconds (1 here) to answer, then runs the job itself."""
    monkeypatch.setenv(jobserver.TIMEOUT_VAR, "1")
    mute = _mute_server(server_socket)
    try:
        code, pid, err = _run_client(tmp_path, timeout=60)
    finally:
        mute.kill()
        mute.wait()
    line = (
        f"bsrbench.jobserver: server not available (no answer from the job server at {server_socket} within "
        "1 s); running in-process"
    )
    assert code == 0 and line in err.splitlines(), err
    assert int((tmp_path / "out.txt").read_text()) == pid


def test_a_result_never_relayed_after_the_worker_ended_makes_the_job_run_in_process(
    server_socket, tmp_path, monkeypatch
):
    """A server that accepts the job but never relays the result of its (ended) worker: the client waits while
    the worker runs, and then BSRBENCH_JOBSERVER_TIMEOUT seconds more."""
    monkeypatch.setenv(jobserver.TIMEOUT_VAR, "1")
    gone = subprocess.Popen(["true"])
    gone.wait()  # a pid that no process has now
    accepted = (
        f'{{"status": "accepted", "detail": null, "worker": {gone.pid}, "server": SERVER_PID}}'
    )
    mute = _mute_server(server_socket, accepted)
    try:
        code, pid, err = _run_client(tmp_path, timeout=60)
    finally:
        mute.kill()
        mute.wait()
    line = (
        f"bsrbench.jobserver: server not available (the job server at {server_socket} did not relay the "
        f"result of its worker {gone.pid} within 1 s of the worker's end); running in-process"
    )
    assert code == 0 and line in err.splitlines(), err
    assert int((tmp_path / "out.txt").read_text()) == pid


def test_a_job_longer_than_the_client_timeout_runs_in_the_server(
    server_socket, tmp_path, monkeypatch
):
    """The client's timeout is for the server's answer, not for the job: a job of 8 s with a timeout of 2 s runs
    in the server to its end."""
    monkeypatch.setenv(jobserver.TIMEOUT_VAR, "2")
    _up(server_socket, tmp_path)
    (tmp_path / "out.txt").unlink()
    jobserver.run(PING, _ping(tmp_path, sleep=8))
    assert int((tmp_path / "out.txt").read_text()) != os.getpid()


# --------------------------------------------------------------------------------------- directory and files
def test_a_parent_others_may_write_to_without_a_sticky_bit_is_refused(
    runtime_base, tmp_path, monkeypatch, capsys
):
    """In a TMPDIR of mode 0777 without the sticky bit another user can replace the job server's directory (it
    did, between the check and the bind); such a parent is refused and the job runs in-process."""
    parent = Path(tempfile.mkdtemp(prefix="bsrjs-", dir="/tmp"))
    try:
        parent.chmod(0o777)
        monkeypatch.delenv("XDG_RUNTIME_DIR")
        monkeypatch.setenv("TMPDIR", str(parent))
        path = parent / f"bsrbench-{os.geteuid()}"
        message = (
            f"unsafe job server directory {path}: its parent {parent} has mode 0777 (others may write to it and "
            "it has no sticky bit, so another user could replace the directory); expected a parent that others "
            "cannot write to, or with the sticky bit (as /tmp, mode 1777)"
        )
        with pytest.raises(jobserver.UnsafeDirectory, match=f"^{re.escape(message)}$"):
            jobserver.socket_path()
        monkeypatch.setattr(sys, "stderr", sys.stderr)  # run_local points stderr at the job's log
        jobserver.run(PING, _ping(tmp_path))
        assert int((tmp_path / "out.txt").read_text()) == os.getpid()
        assert f"bsrbench.jobserver: {message}; running in-process" in capsys.readouterr().err
        assert list(parent.iterdir()) == []  # nothing made there
        parent.chmod(0o1777)  # with the sticky bit, as /tmp: used
        assert jobserver.runtime_dir() == path
    finally:
        shutil.rmtree(parent)


#: Serve on argv[1], after replacing the socket's directory with a link to argv[3] (the directory moved to
#: argv[2]) right before the listening socket is made: after every check, before the bind.
SWAPPED_SERVER = """
import os, socket, sys
from bsrbench import jobserver
path, moved, elsewhere = sys.argv[1:4]
make_socket = socket.socket
def swap_then_make(*args, **kwargs):
    if not os.path.exists(moved):
        os.rename(os.path.dirname(path), moved)
        os.symlink(elsewhere, os.path.dirname(path))
    return make_socket(*args, **kwargs)
socket.socket = swap_then_make
jobserver.serve(path, idle=60)
"""


def test_a_directory_swapped_after_the_check_redirects_nothing(runtime_base, tmp_path):
    """The socket was bound through the path, so a directory swapped for a link after the check put it (and the
    server's lock) where the link led; now the server binds in the directory it checked (through its
    descriptor), wherever that was moved, and removes its files there."""
    path = jobserver.socket_path(cwd=tmp_path)
    moved, elsewhere = runtime_base / "moved", runtime_base / "elsewhere"
    elsewhere.mkdir(mode=0o700)
    with open(tmp_path / "server.log", "w") as log:
        server = subprocess.Popen(
            [sys.executable, "-c", SWAPPED_SERVER, str(path), str(moved), str(elsewhere)],
            stderr=log,
        )
    try:
        deadline = time.monotonic() + 60
        while not (moved / path.name).exists() and not (elsewhere / path.name).exists():
            assert time.monotonic() < deadline and server.poll() is None, (
                tmp_path / "server.log"
            ).read_text()
            time.sleep(0.05)
        assert path.parent.is_symlink()  # swapped
        assert list(elsewhere.iterdir()) == []
        assert jobserver.shutdown(moved / path.name) is True
        assert server.wait(timeout=60) == 0, (tmp_path / "server.log").read_text()
        assert list(elsewhere.iterdir()) == [] and list(moved.iterdir()) == []
    finally:
        server.kill()
        server.wait()


@pytest.mark.parametrize("planted", [".lock", ".log", ".log hard link"])
def test_lock_and_log_links_planted_beside_a_given_socket_are_not_followed(
    runtime_base, tmp_path, monkeypatch, planted
):
    """Beside a socket given by BSRBENCH_JOBSERVER_SOCKET (here in a directory like /tmp, where others may create
    files), a link in place of the lock or the log was followed, creating or writing the file it names; now they
    are refused (one line) and the job runs in-process."""
    shared = Path(tempfile.mkdtemp(prefix="bsrjs-", dir="/tmp"))
    try:
        shared.chmod(0o1777)
        sock = shared / "s.sock"
        monkeypatch.setenv(jobserver.SOCKET_VAR, str(sock))
        suffix = planted.split()[0]
        target = tmp_path / "victim"
        uid = os.geteuid()
        if planted.endswith("hard link"):
            target.write_text("precious")
            os.link(target, f"{sock}{suffix}")
            found = f"a file owned by uid {uid} with 2 links"
        else:
            Path(f"{sock}{suffix}").symlink_to(target)
            found = f"a symbolic link owned by uid {uid}"
        code, pid, err = _run_client(tmp_path, timeout=120)
        line = (
            f"bsrbench.jobserver: unsafe job server file {sock}{suffix}: {found}; expected a regular file owned "
            f"by uid {uid} (this user) with one link; running in-process"
        )
        if planted.endswith("hard link"):
            assert target.read_text() == "precious"
        else:
            assert not target.exists()  # the link was not followed
        assert not sock.exists()  # no server was started
        assert code == 0 and line in err.splitlines(), err
        assert int((tmp_path / "out.txt").read_text()) == pid
    finally:
        jobserver.shutdown(sock)
        shutil.rmtree(shared)


def test_a_given_socket_in_a_directory_others_may_replace_files_in_is_refused(
    tmp_path, monkeypatch
):
    shared = Path(tempfile.mkdtemp(prefix="bsrjs-", dir="/tmp"))
    try:
        shared.chmod(0o777)
        monkeypatch.setenv(jobserver.SOCKET_VAR, str(shared / "s.sock"))
        code, pid, err = _run_client(tmp_path, timeout=120)
        line = (
            f"bsrbench.jobserver: unsafe job server directory {shared}: a directory owned by uid {os.geteuid()} "
            f"with mode 0777; expected a directory owned by uid {os.geteuid()} (this user) or root that others "
            "cannot write to, or with the sticky bit (as /tmp, mode 1777); running in-process"
        )
        assert code == 0 and line in err.splitlines(), err
        assert list(shared.iterdir()) == []
    finally:
        jobserver.shutdown(shared / "s.sock")
        shutil.rmtree(shared)


# ----------------------------------------------------------------------------------------------------- logs
#: A job module whose warm-up warns, as a library may when the server preloads it.
WARNING_MODULE = """
import warnings
def warm_up():
    warnings.warn("a library deprecates something\\n  over two lines", FutureWarning)
"""


@pytest.mark.parametrize("end", ["shut down", "killed"])
def test_a_log_holding_only_warnings_is_no_server_failure(server_socket, tmp_path, end, capsys):
    """A library's warning in the server's log kept the log as a record of a server failure (and named it); now
    a warning is one marked line, and a log of warnings only is removed like an empty one. Any other line keeps
    it."""
    (tmp_path / "warnmod.py").write_text(WARNING_MODULE)
    env = dict(os.environ, PYTHONPATH=str(tmp_path))
    log_path = Path(f"{server_socket}.log")
    with open(log_path, "a") as log:
        server = subprocess.Popen(
            [sys.executable, "-m", "bsrbench.jobserver", str(server_socket), "warnmod"],
            stderr=log,
            env=env,
            start_new_session=True,
        )
    deadline = time.monotonic() + 120
    while not server_socket.exists():
        assert time.monotonic() < deadline and server.poll() is None, log_path.read_text()
        time.sleep(0.05)
    jobserver.run(PING, _ping(tmp_path))
    lines = log_path.read_text().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        "bsrbench.jobserver: warning: FutureWarning: a library deprecates something over two lines ("
    ), lines
    if end == "killed":
        server.kill()
    else:
        assert jobserver.shutdown(server_socket) is True
    server.wait(timeout=60)
    capsys.readouterr()
    jobserver.shutdown(server_socket)  # tidies up after a killed server
    assert _server_files(server_socket) == []
    assert "(kept)" not in capsys.readouterr().err
    # a line that is not a warning: kept and named
    log_path.write_text(lines[0] + "\nTraceback (most recent call last):\n")
    assert jobserver.shutdown(server_socket) is False
    assert f"the server wrote to {log_path} (kept)" in capsys.readouterr().err
    assert _server_files(server_socket) == [log_path.name]


def test_a_killed_client_still_kills_its_worker_after_the_acknowledgement(server_socket, tmp_path):
    """The "accepted" answer changes nothing of the rest: a client that goes away still takes its worker along."""
    pid_file = tmp_path / "worker.pid"
    job = _ping(tmp_path, sleep=60, pid_file=str(pid_file))
    code = f"from bsrbench import jobserver; jobserver.run({PING!r}, {job!r})"
    client = subprocess.Popen([sys.executable, "-c", code], env=dict(os.environ))
    deadline = time.monotonic() + 60
    while not pid_file.exists():
        assert time.monotonic() < deadline
        time.sleep(0.02)
    worker = int(pid_file.read_text())
    client.send_signal(signal.SIGKILL)
    client.wait()
    _wait_gone(worker, timeout=10)


def test_a_request_whose_cwd_does_not_exist_gets_one_line_and_the_server_serves_on(
    server_socket, tmp_path
):
    """A ``cwd`` naming no directory failed in the worker's chdir: its reply was a Python traceback, which also
    went into the server's log and kept it as the record of a server failure. Now it is refused in one line, no
    job runs, the server serves on and its log is removed at shutdown like an empty one."""
    server_pid = _up(server_socket, tmp_path)
    output = tmp_path / "ran.txt"
    for cwd, what in [
        (tmp_path / "gone", "does not exist"),
        (tmp_path / "f", "is not a directory"),
    ]:
        if what == "is not a directory":
            cwd.write_text("")
        request = dict(_request(tmp_path, output), cwd=str(cwd))
        reply = _ask(server_socket, _frame(request))
        assert reply == {
            "status": "error",
            "detail": f"refused a request: field 'cwd' is {str(cwd)!r}, which {what}; expected an existing "
            "directory",
        }
    assert not output.exists()
    _serves_on(server_socket, server_pid, tmp_path)
    assert jobserver.shutdown(server_socket) is True
    assert _server_files(server_socket) == []
