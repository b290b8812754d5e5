"""A local fork server for the study's short jobs: one warm Python process, one fork per job.

The study's fits run in thousands of short jobs (one per seed, or one per block of seeds that runs the job of each
seed in turn, or one per split that runs its chains, :func:`run_block`), and most fits compute for well under a
second, while a fresh interpreter spends about 1.8 s of CPU importing scikit-learn (which imports scipy.stats and
pandas) and loading numba's cached kernels. On a 2-core machine that is over half of the paper protocol's wall time. The rules' shell commands
(``python -m bsrbench.jobserver job``) therefore hand their job to a server that has done those imports once (the job
module's ``PRELOAD`` and the ``warm_up()`` of its modules, see :func:`_preload`) and forks a child per job (the pattern of Python's ``multiprocessing`` forkserver, here reachable from independent processes through
a Unix socket). The child runs exactly the code the job would run in-process, with the job's log as its stdout and
stderr, and results are identical.

Lifecycle and safety:
- One server per environment and working directory. The first job starts it (``python -m bsrbench.jobserver``)
  in its own session; a lock file keeps concurrent jobs from starting two.
- It stops when the Snakemake run that started it ends: the Snakefile's ``onsuccess``/``onerror`` handlers
  call :func:`shutdown`; if Snakemake is killed instead, the server notices that the run's main process (its
  pid travels with every request, from ``BSRBENCH_JOBSERVER_OWNER``, which the Snakefile sets) is gone; and
  it exits after ``IDLE_SECONDS`` without jobs in any case. On exit it removes its socket, its lock file and its
  log (the log only when empty: a non-empty one records a server failure and is kept).
- Every request carries a fingerprint of the package's source files (paths, sizes, mtimes) and of the
  interpreter. A server started from other code answers "stale" and exits, and the job starts a fresh one,
  so an edited model never runs with old code.
- Each job is one fork (the worker); the server relays its result and watches the client's connection: if the
  client dies (Snakemake interrupted), the worker is killed. Outputs are written atomically, so nothing half-written
  is left.
- Threads: the child limits numba and BLAS to the job's ``threads``.
- Only this user: the socket, lock and log live in a directory private to the user (:func:`runtime_dir`,
  refused if another user owns it or may enter it); client and server check each other's uid on the socket
  (``SO_PEERCRED``) and close a foreign peer's connection unread; and they exchange plain JSON, never pickles, so
  no peer can make the other run code by what it sends.
- If the server cannot be reached, started or trusted, or ``use_server`` is false (cluster executors, where jobs
  run on other nodes), the job runs in the calling process (with one line on stderr why).
"""

import errno
import fcntl
import gc
import hashlib
import importlib
import json
import os
import select
import signal
import socket
import stat
import struct
import sys
import time
from pathlib import Path

#: The server exits after this long without a job (a fallback: the run's end stops it, see the module docstring).
IDLE_SECONDS = 120.0
#: Environment variable holding the pid of the Snakemake process whose run the jobs belong to.
OWNER_VAR = "BSRBENCH_JOBSERVER_OWNER"
#: How long a job waits for a server it started to listen.
START_TIMEOUT = 60.0
_PKG = Path(__file__).resolve().parent
#: Environment variables that set the thread counts of numba and of the BLAS/OpenMP libraries.
_THREAD_VARS = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


# ------------------------------------------------------------------------------------------------- framing
#: Largest message accepted (a job spec or a traceback is a few kB).
_MAX_MESSAGE = 1 << 24


class ProtocolError(OSError):
    """A peer sent something that is not a message of this protocol (or a message could not be encoded)."""


class PeerRefused(OSError):
    """The process at the other end of the socket runs as another user (or its user cannot be checked)."""


class UnsafeDirectory(OSError):
    """The job server's directory exists but is not private to this user."""


def _send(sock, obj):
    """Send ``obj`` as JSON, prefixed with its length."""
    try:
        data = json.dumps(obj).encode()
    except (TypeError, ValueError) as exc:
        raise ProtocolError(f"message not JSON-serializable: {exc}") from None
    sock.sendall(struct.pack("!Q", len(data)) + data)


def _recv_exact(sock, n):
    buf = bytearray()
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise EOFError("connection closed")
        buf += chunk
    return bytes(buf)


def _recv(sock):
    """Receive one message of :func:`_send`: plain data (dicts, lists, strings, numbers), whatever the peer sent."""
    (n,) = struct.unpack("!Q", _recv_exact(sock, 8))
    if n > _MAX_MESSAGE:
        raise ProtocolError(f"message of {n} bytes announced, more than {_MAX_MESSAGE}")
    try:
        return json.loads(_recv_exact(sock, n))
    except (UnicodeDecodeError, ValueError):
        raise ProtocolError("a message that is not JSON") from None


def _reply(status, detail=None):
    return {"status": status, "detail": detail}


def _check_reply(reply):
    """(status, detail) of a server's reply; ProtocolError unless it is one."""
    if (
        not isinstance(reply, dict)
        or reply.get("status") not in ("ok", "error", "stale", "bye")
        or not isinstance(reply.get("detail"), (str, type(None)))
    ):
        raise ProtocolError("a reply that is not a job server's")
    return reply["status"], reply["detail"]


def _peer_uid(sock):
    """The uid of the process at the other end of the Unix socket ``sock`` (for a client: the process that listens;
    for the server: the process that connected), from the kernel (``SO_PEERCRED``)."""
    if not hasattr(socket, "SO_PEERCRED"):
        raise PeerRefused("this platform has no SO_PEERCRED to check the job server's user")
    ucred = struct.Struct("3i")  # struct ucred: pid, uid, gid
    _, uid, _ = ucred.unpack(sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, ucred.size))
    return uid


# --------------------------------------------------------------------------------------------- identities
def fingerprint():
    """Hash of the interpreter and of every source file of the package (path, size, mtime)."""
    h = hashlib.sha256(f"{sys.executable}|{sys.version}".encode())
    for path in sorted(_PKG.rglob("*.py")):
        st = path.stat()
        h.update(f"{path}|{st.st_size}|{st.st_mtime_ns}".encode())
    return h.hexdigest()


def runtime_dir():
    """This user's private directory for the server's socket, lock and log, created if absent:
    ``$XDG_RUNTIME_DIR/bsrbench``, else ``$TMPDIR/bsrbench-<uid>`` (``/tmp`` without ``TMPDIR``).

    Like ssh-agent's and tmux's, it must be a real directory (not a link) owned by this user with no access for
    group or others: otherwise another user could put a socket of theirs where the jobs connect, or read the
    log. Raises :class:`UnsafeDirectory` (naming the path, the owner and mode found, and what is expected)."""
    uid = os.geteuid()
    base = os.environ.get("XDG_RUNTIME_DIR")
    if base:
        path = Path(base) / "bsrbench"
    else:
        path = Path(os.environ.get("TMPDIR") or "/tmp") / f"bsrbench-{uid}"
    try:
        # the umask can only remove bits of 0700; chmod restores the owner's, which a umask of 0o777 would remove
        os.mkdir(path, 0o700)
        os.chmod(path, 0o700)
    except FileExistsError:
        pass
    st = os.lstat(path)  # whatever was there before: check it, do not follow it
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != uid or st.st_mode & 0o077:
        kinds = {
            stat.S_ISDIR: "a directory",
            stat.S_ISLNK: "a symbolic link",
            stat.S_ISREG: "a file",
        }
        kind = next((k for test, k in kinds.items() if test(st.st_mode)), "not a directory")
        raise UnsafeDirectory(
            f"unsafe job server directory {path}: {kind} owned by uid {st.st_uid} with mode "
            f"{stat.S_IMODE(st.st_mode):04o}; expected a directory owned by uid {uid} (this user) with mode "
            "0700 (no access for group or others)"
        )
    return path


def socket_path(cwd=None):
    """The server's socket in :func:`runtime_dir`, one per environment and working directory (``cwd``, default the
    current one); the server's lock and log files are this path + ``.lock`` and ``.log``.
    ``BSRBENCH_JOBSERVER_SOCKET`` overrides it, as given (benchmarks run servers of other revisions there)."""
    if os.environ.get("BSRBENCH_JOBSERVER_SOCKET"):
        return Path(os.environ["BSRBENCH_JOBSERVER_SOCKET"])
    cwd = Path(cwd or os.getcwd()).resolve()
    key = hashlib.sha256(f"{sys.prefix}|{_PKG}|{cwd}".encode()).hexdigest()[:16]
    return runtime_dir() / f"jobserver-{key}.sock"


# ------------------------------------------------------------------------------------------------- running
def _plain(value):
    if isinstance(value, (str, bytes, int, float, bool, type(None), dict)):
        return value
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _named(nl):
    return {name: _plain(val) for name, val in nl.items()}


def job_params():
    """A Snakemake ``params`` function: the job's named input, output and wildcards as JSON, for a shell rule
    that runs ``python -m bsrbench.jobserver job TARGET --threads {threads} --log {log} JOB --settings SETTINGS``
    (SETTINGS: :func:`job_settings`).

    A shell command starts in about 0.06 s where a ``script:`` job spends about 0.25 s importing Snakemake's
    script module, which in a study of thousands of sub-second jobs is minutes of wall time
    (benchmarks/profile_study.py).
    """
    import json

    def job(wildcards, input, output):
        return json.dumps(
            {"input": _named(input), "output": _named(output), "wildcards": _named(wildcards)},
            sort_keys=True,
        )

    return job


def _step_input(input):
    """A block step's named inputs: the job's, but ``code`` (the source files, inputs for Snakemake's code trigger
    that no job reads), so that a block's command line stays short (a step would repeat some 2,000 characters of
    paths, and a long block would pass the kernel's limit on a command's arguments)."""
    return {name: val for name, val in _named(input).items() if name != "code"}


def block_job_params(seeds, per_seed_input=None):
    """A Snakemake ``params`` function like :func:`job_params` for a job that runs a block of seeds: the JSON
    ``{"block": [spec, ...]}``, one spec per seed of ``seeds`` (in order), each the spec that :func:`job_params`
    gives the one-seed job of that seed: its wildcards with ``seed``, its output files (the block's named outputs
    are lists with one file per seed, in seed order), the block's named inputs but ``code``, except those of
    ``per_seed_input`` ({name: function of the seed's wildcards (attributes) to the input, as the one-seed rule's
    input function})."""
    import json
    from types import SimpleNamespace

    def job(wildcards, input, output):
        specs = []
        for i, seed in enumerate(seeds):
            w = {**_named(wildcards), "seed": str(seed)}
            inp = _step_input(input)
            for name, get in (per_seed_input or {}).items():
                inp[name] = _plain(get(SimpleNamespace(**w)))
            out = {name: files[i] for name, files in _named(output).items()}
            specs.append({"input": inp, "output": out, "wildcards": w})
        return json.dumps({"block": specs}, sort_keys=True)

    return job


def chains_job_params(n_chains):
    """A Snakemake ``params`` function like :func:`job_params` for a job that runs the ``n_chains`` chains of one
    split: the JSON ``{"block": [chain 0, ..., chain C-1]}`` for :func:`run_block`, chain c's spec the one a
    one-chain job has (the job's named inputs but ``code``, output ``chain``: the job's ``chains`` file c, the
    wildcards with ``chain``)."""
    import json

    def job(wildcards, input, output):
        w, inp, out = _named(wildcards), _step_input(input), _named(output)
        steps = [
            {
                "input": inp,
                "output": {"chain": out["chains"][c]},
                "wildcards": {**w, "chain": str(c)},
            }
            for c in range(n_chains)
        ]
        return json.dumps({"block": steps}, sort_keys=True)

    return job


def job_settings(params):
    """A Snakemake ``params`` function: ``params`` (names to values or to functions of the wildcards) evaluated,
    as JSON: the job's ``params``. It depends on the wildcards only, so Snakemake's params trigger records it
    and a changed setting reruns the job."""
    import json

    def settings(wildcards):
        values = {k: (v(wildcards) if callable(v) else v) for k, v in params.items()}
        return json.dumps(values, sort_keys=True)

    return settings


def _resolve(target):
    module, name = target.split(":")
    return getattr(importlib.import_module(module), name)


#: BLAS/OpenMP threads of the serving process, which its forks inherit (None: not a server).
_SERVER_BLAS_THREADS = None


def _limit_blas(threads):
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(int(threads))
    except ImportError:
        pass


def _limit_threads(threads):
    """Limit numba and BLAS/OpenMP to ``threads`` in an already-initialized process (a fork of the server)."""
    for var in _THREAD_VARS:
        if var != "NUMBA_NUM_THREADS":
            os.environ[var] = str(threads)  # for any subprocess of the job
    # NUMBA_NUM_THREADS stays the server's: numba re-reads the environment whenever it compiles (e.g. ArviZ's
    # ufuncs in a pool_chains job) and refuses a value other than that of its launched thread pool.
    try:
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))
    except ImportError:
        pass
    if int(threads) != _SERVER_BLAS_THREADS:
        _limit_blas(threads)


def run_local(target, job):
    """Run ``target`` (``"module:function"``) on ``job`` in this process, log to the job's log file."""
    threads = str(job.get("threads", 1))
    for var in _THREAD_VARS:
        os.environ[var] = threads  # before numba and BLAS are imported
    log = job.get("log") or []
    if log:
        sys.stderr = open(log[0], "a" if job.get("log_append") else "w", buffering=1)
    _resolve(target)(job)


#: Environment variables that batch systems set inside a submitted job: such a job runs on a compute node, where
#: a job server would only add a start-up per job, so it runs in-process whatever the config key job_server says
#: (a command-line ``--config`` replaces the SLURM profile's own ``job_server=False``).
_BATCH_JOB_VARS = ("SLURM_JOB_ID", "PBS_JOBID", "LSB_JOBID")


def in_batch_job():
    """True inside a job submitted to SLURM, PBS/Torque or LSF (see :data:`_BATCH_JOB_VARS`)."""
    return any(os.environ.get(var) for var in _BATCH_JOB_VARS)


def run(target, job, *, use_server=True):
    """Run a job: in a fork of the warm server if possible, else in this process (always in this process inside a
    batch-system job, :func:`in_batch_job`)."""
    if use_server and not in_batch_job():
        try:
            status, detail = _run_remote(target, job)
        except (PeerRefused, UnsafeDirectory) as exc:
            print(f"bsrbench.jobserver: {exc}; running in-process", file=sys.stderr)
        except (OSError, EOFError, TimeoutError) as exc:
            print(
                f"bsrbench.jobserver: server not available ({exc}); running in-process",
                file=sys.stderr,
            )
        else:
            if status == "ok":
                return
            log = (job.get("log") or ["(no log)"])[0]
            raise SystemExit(f"job {target} failed in the job server; see {log}:\n{detail}")
    run_local(target, job)


def _step(spec):
    """A step of a block job, as its messages name it: ``seed 3``, or ``seed 3 chain 1`` for one chain of a split."""
    w = spec["wildcards"]
    return f"seed {w['seed']}" + (f" chain {w['chain']}" if "chain" in w else "")


def run_block(target, specs, *, params, threads, log, use_server=True):
    """Run the steps of a block job one after the other, each as :func:`run` runs a one-step job, all logging to
    the block's ``log`` (emptied first). A step is the job of one seed (:func:`block_job_params`) or of one chain
    of a split (:func:`chains_job_params`). Stops at the first step that fails, with a message naming it
    (SystemExit); Snakemake then removes the outputs of the whole block, and reruns it whole."""
    import traceback

    if log:
        open(log[0], "w").close()
    seeds = [spec["wildcards"]["seed"] for spec in specs]
    what = (
        f"the chains of seed {seeds[0]}"
        if "chain" in specs[0]["wildcards"]
        else f"the block of seeds {seeds[0]}-{seeds[-1]}"
    )
    for spec in specs:
        step = _step(spec)
        job = dict(spec, params=params, threads=threads, log=log, log_append=True)
        if log:
            with open(log[0], "a") as f:
                print(f"--- {step} ---", file=f)
        stderr = sys.stderr
        try:
            run(target, job, use_server=use_server)
        except (Exception, SystemExit) as exc:
            # raised in this process (run_local): its traceback into the log
            if not isinstance(exc, SystemExit):
                traceback.print_exc()
                exc = f"{type(exc).__name__}: {exc}"
            where = f"; see {log[0]}" if log else ""
            raise SystemExit(f"{target}: {step} of {what} failed{where}:\n{exc}") from None
        finally:
            # run in this process, the job's stderr was its log: the block's message goes to the command's
            if sys.stderr is not stderr:
                sys.stderr.close()
                sys.stderr = stderr


def _connect(path):
    """A connection to the server at ``path``; :class:`PeerRefused` (closed unwritten) if it runs as another
    user."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.connect(str(path))
        uid = _peer_uid(sock)
    except OSError:
        sock.close()
        raise
    if uid != os.geteuid():
        sock.close()
        raise PeerRefused(
            f"refused the server at {path}: it runs as uid {uid}, not as this user (uid {os.geteuid()})"
        )
    return sock


def _locked(path):
    """Open and lock ``<path>.lock``; retry if an exiting server unlinked the file while we waited for it."""
    lock_path = f"{path}.lock"
    while True:
        lock = open(lock_path, "a")
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if os.stat(lock_path).st_ino == os.fstat(lock.fileno()).st_ino:
                return lock
        except FileNotFoundError:
            pass
        lock.close()


def _start_server(path, preload=()):
    """Start a server (preloading the modules ``preload``) unless another job is starting one; wait until it
    listens."""
    import subprocess  # here, not at the top: a job's client never starts a server once one runs

    lock = _locked(path)
    try:
        try:
            return _connect(path)
        except PeerRefused:
            raise  # never replace a foreign server's socket: the job runs in-process
        except OSError:
            pass
        env = dict(os.environ)
        for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
            env[var] = (
                "1"  # no BLAS thread pools in the process that forks; children may raise them
            )
        env["NUMBA_NUM_THREADS"] = str(os.cpu_count() or 1)
        subprocess.Popen(
            [sys.executable, "-m", "bsrbench.jobserver", str(path), *preload],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=open(f"{path}.log", "a"),
            start_new_session=True,
            env=env,
        )
        deadline = time.monotonic() + START_TIMEOUT
        while time.monotonic() < deadline:
            try:
                return _connect(path)
            except PeerRefused:
                raise
            except OSError:
                time.sleep(0.05)
        raise TimeoutError(
            f"job server at {path} did not start within {START_TIMEOUT:.0f} s (log: {path}.log)"
        )
    finally:
        lock.close()


def _run_remote(target, job):
    path = socket_path()
    fp = fingerprint()
    for _ in range(2):
        try:
            sock = _connect(path)
        except PeerRefused:
            raise
        except OSError:
            sock = _start_server(path, preload=[target.split(":")[0]])
        with sock:
            _send(
                sock,
                {
                    "target": target,
                    "job": job,
                    "fingerprint": fp,
                    "cwd": os.getcwd(),
                    "owner": _owner(),
                },
            )
            status, detail = _check_reply(_recv(sock))
        if status != "stale":
            return status, detail
        # the server ran other code: it is shutting down; wait for its socket to go, then start a new one
        deadline = time.monotonic() + 10
        while path.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
    raise OSError(errno.EAGAIN, "job server stayed stale")


def _owner():
    try:
        return int(os.environ.get(OWNER_VAR, ""))
    except ValueError:
        return None


def shutdown(path=None, timeout=30.0):
    """Stop the job server of this working directory (or at ``path``) and wait until its files are gone.

    Called by the Snakefile's ``onsuccess`` and ``onerror`` handlers. Without a listening server, removes what a
    killed one left (socket, lock, empty log). Returns True if a server was stopped; never raises.
    """
    try:
        path = Path(path) if path else socket_path()
        try:
            sock = _connect(path)
        except PeerRefused:
            raise  # not ours to stop or to remove
        except OSError:
            with _locked(path) as lock:  # no server: tidy up, unless one starts right now
                try:
                    _connect(path).close()
                except PeerRefused:
                    raise
                except OSError:
                    _remove_files(path, lock, socket_ino=None)
            return False
        with sock:
            _send(sock, {"shutdown": True})
            try:
                _recv(sock)
            except (EOFError, OSError):
                pass
        deadline = time.monotonic() + timeout
        while Path(f"{path}.lock").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        return True
    except Exception as exc:
        where = f" at {path}" if path else ""
        print(f"bsrbench.jobserver: could not stop the server{where}: {exc}", file=sys.stderr)
        return False


def _remove_files(path, lock, socket_ino):
    """Remove the socket (if ``socket_ino`` is None or it is still that inode), the empty log and the lock
    (while ``lock``, its open file, holds the lock, so that no client is starting a server meanwhile)."""
    path = Path(path)
    try:
        if socket_ino is None or os.stat(path).st_ino == socket_ino:
            path.unlink()
    except FileNotFoundError:
        pass
    log = Path(f"{path}.log")
    try:
        st = log.stat()
        if st.st_size == 0:
            log.unlink()
        elif not os.path.samestat(os.fstat(2), st):  # not into the log itself (a server's stderr)
            print(f"bsrbench.jobserver: the server wrote to {log} (kept)", file=sys.stderr)
    except FileNotFoundError:
        pass
    try:
        os.unlink(lock.name)
    except FileNotFoundError:
        pass


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def ping(job):
    """A health-check job: write ``job["output"]["path"]`` (the worker's pid), optionally after sleeping
    ``job["params"]["sleep"]`` seconds, or raise if ``job["params"]["fail"]``."""
    params = job.get("params", {})
    print(f"ping from pid {os.getpid()}", file=sys.stderr)
    if params.get("pid_file"):  # written whole (a rename), so that a reader never sees it empty
        from .io import atomic_path  # in a worker: preloaded by the server

        with atomic_path(params["pid_file"]) as tmp:
            tmp.write_text(str(os.getpid()))
    time.sleep(float(params.get("sleep", 0)))
    if params.get("fail"):
        raise ValueError(f"ping asked to fail: {params['fail']}")
    Path(job["output"]["path"]).write_text(str(os.getpid()))


# -------------------------------------------------------------------------------------------------- server
def _worker(request, conn, result_w, inherited):
    """The forked worker: the job's directory, log and threads, then the job itself; its result goes to the pipe
    ``result_w``. ``inherited``: the server's descriptors (listening socket, other jobs' connections and pipes)."""
    import traceback

    for fd in inherited:
        try:
            os.close(fd)
        except OSError:
            pass
    conn.close()
    status, detail = "ok", None
    try:
        os.chdir(request["cwd"])
        job = request["job"]
        log = job.get("log") or []
        if log:
            mode = os.O_APPEND if job.get("log_append") else os.O_TRUNC
            fd = os.open(log[0], os.O_WRONLY | os.O_CREAT | mode, 0o644)
            os.dup2(fd, 1)
            os.dup2(fd, 2)
            os.close(fd)
        sys.stdout = os.fdopen(1, "w", buffering=1, closefd=False)
        sys.stderr = os.fdopen(2, "w", buffering=1, closefd=False)
        _limit_threads(job.get("threads", 1))
        _resolve(request["target"])(job)
    except BaseException:
        detail = traceback.format_exc()
        status = "error"
        print(detail, file=sys.stderr)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        os.write(result_w, json.dumps(_reply(status, detail)).encode())
    finally:
        os._exit(0)  # never return into the server's code, whatever failed


#: libc's ``prctl`` in a serving process (None elsewhere, or where libc has none), for :func:`_die_with_server`.
_PRCTL = None


def _die_with_server(server_pid):
    """Have the kernel kill this worker if the server dies (Linux ``PR_SET_PDEATHSIG``): its client then runs the
    job in-process, and nothing else may write the job's outputs."""
    if _PRCTL is None:
        return
    _PRCTL(1, int(signal.SIGKILL))  # 1: PR_SET_PDEATHSIG
    if os.getppid() != server_pid:  # the server died before the call
        os._exit(1)


def _find_prctl():
    import ctypes

    try:
        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None


def _describe_exit(status):
    """A worker's wait status in words: the exit code, or the signal by name (SIGKILL is what the kernel's
    out-of-memory killer sends)."""
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        try:
            name = signal.Signals(sig).name
        except ValueError:
            name = f"signal {sig}"
        hint = (
            " (killed from outside, e.g. by the out-of-memory killer)"
            if sig == signal.SIGKILL
            else ""
        )
        return f"was killed by {name}{hint}"
    return f"exited with code {os.waitstatus_to_exitcode(status)}"


class _Job:
    """A running job as the server sees it: the worker's pid, the client's connection, the worker's result pipe."""

    def __init__(self, pid, conn, result_r, log=None):
        self.pid, self.conn, self.result_r, self.chunks = pid, conn, result_r, []
        # the job's log file (absolute): a worker that died says nothing there itself
        self.log = log

    def relay(self):
        """Read the worker's result pipe; at its end, reap the worker and send its result to the client. True when
        the job is over."""
        data = os.read(self.result_r, 1 << 16)
        if data:
            self.chunks.append(data)
            return False
        _, status = os.waitpid(self.pid, 0)
        try:
            result = json.loads(b"".join(self.chunks))
        except ValueError:
            result = _reply("error", f"worker {_describe_exit(status)} without a result")
            self._note(result["detail"])
        try:
            _send(self.conn, result)
        except OSError:
            pass
        self.close()
        return True

    def _note(self, line):
        """Append ``line`` to the job's log: the client's message sends the user there ("see <log>")."""
        if self.log is None:
            return
        try:
            with open(self.log, "a") as f:
                print(line, file=f)
        except OSError:
            pass

    def kill(self):
        """The client closed its connection (its job was killed): kill the worker, so it writes nothing more."""
        os.kill(self.pid, signal.SIGKILL)
        os.waitpid(self.pid, 0)
        self.close()

    def close(self):
        os.close(self.result_r)
        self.conn.close()


def _start_job(conn, request, srv, jobs):
    """Fork the worker of ``request``; the server watches its pipe and the client's connection (:class:`_Job`)."""
    result_r, result_w = os.pipe()
    inherited = [srv.fileno()] + [
        fd for job in jobs.values() for fd in (job.conn.fileno(), job.result_r)
    ]
    server_pid = os.getpid()
    pid = os.fork()
    if pid == 0:
        _die_with_server(server_pid)
        os.close(result_r)
        _worker(request, conn, result_w, inherited)
    os.close(result_w)
    log = request["job"].get("log")
    log = log[0] if isinstance(log, list) and log and isinstance(log[0], str) else None
    return _Job(pid, conn, result_r, log and os.path.join(request["cwd"], log))


def _preload(modules):
    """Import the job modules ``modules`` and the modules each lists in its ``PRELOAD``, and run the
    ``warm_up()`` of those that have one (e.g. a model loading its numba kernels): what every forked job would
    otherwise do itself."""
    import traceback

    for name in modules:
        try:
            module = importlib.import_module(name)
        except ImportError:
            traceback.print_exc()
            continue
        for dep in [name, *getattr(module, "PRELOAD", ())]:
            try:
                warm_up = getattr(importlib.import_module(dep), "warm_up", None)
                if callable(warm_up):
                    warm_up()
            except Exception:
                traceback.print_exc()  # a failed warm-up only costs the jobs time


def _check_request(request):
    """``request`` if it is a shutdown or a job request (:func:`_run_remote`); ProtocolError if not."""
    if isinstance(request, dict) and request.get("shutdown") is True:
        return request
    if not (
        isinstance(request, dict)
        and all(isinstance(request.get(k), str) for k in ("target", "fingerprint", "cwd"))
        and isinstance(request.get("job"), dict)
        and isinstance(request.get("owner"), (int, type(None)))
    ):
        raise ProtocolError("a request that is not a job server's")
    return request


def serve(path, idle=IDLE_SECONDS, preload=()):
    """Import the job modules ``preload`` (:func:`_preload`), listen on ``path`` and fork a worker per request,
    relaying each worker's result to its client, until asked to shut down, until every Snakemake process it served
    for is gone, or until idle for ``idle`` seconds; then finish the running jobs and remove its files."""
    global _SERVER_BLAS_THREADS, _PRCTL
    _preload(preload)
    _PRCTL = _find_prctl()
    # once here rather than in every worker: threadpoolctl's scan of the loaded libraries costs tens of ms
    _limit_blas(1)
    _SERVER_BLAS_THREADS = 1
    # Move everything imported so far out of the garbage collector's reach: a forked job that runs a collection
    # would otherwise write to (and so copy) every page of the server's objects.
    gc.freeze()
    fp = fingerprint()
    path = Path(path)
    if path.exists():
        path.unlink()
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    srv.bind(str(path))
    socket_ino = os.stat(path).st_ino
    srv.listen(64)
    jobs, owners, last, accepting = {}, set(), time.monotonic(), True
    try:
        while accepting or jobs:
            watched = [srv] if accepting else []
            for job in jobs.values():
                watched += [job.result_r, job.conn]
            ready = set(select.select(watched, [], [], 1.0)[0])
            for key, job in list(jobs.items()):
                if job.result_r in ready:
                    if job.relay():
                        del jobs[key]
                elif job.conn in ready:  # the client should not send more: readable means it closed
                    job.kill()
                    del jobs[key]
            if jobs:
                last = time.monotonic()
            if not accepting:
                continue
            if srv not in ready:
                if not jobs and time.monotonic() - last > idle:
                    accepting = False
                elif not jobs and owners and not any(_alive(pid) for pid in owners):
                    accepting = False  # the Snakemake run ended without the shutdown hook (killed)
                continue
            conn, _ = srv.accept()
            last = time.monotonic()
            try:
                uid = _peer_uid(conn)
            except OSError:
                uid = None
            if uid != os.geteuid():  # closed unread: nothing a foreign process sends is even parsed
                conn.close()
                print(
                    f"bsrbench.jobserver: refused a client of uid {uid} (this server runs as uid "
                    f"{os.geteuid()})",
                    file=sys.stderr,
                    flush=True,
                )
                continue
            try:
                conn.settimeout(
                    10.0
                )  # a client that connects and sends nothing must not stall the server
                request = _check_request(_recv(conn))
                conn.settimeout(None)
            except (EOFError, OSError):
                conn.close()
                continue
            if request.get("shutdown"):
                _send(conn, _reply("bye"))
                conn.close()
                accepting = False
                continue
            if request.get("owner"):
                owners.add(int(request["owner"]))
            if request.get("fingerprint") != fp:  # the client hashed the sources just now
                _send(conn, _reply("stale"))
                conn.close()
                accepting = False
                continue
            job = _start_job(conn, request, srv, jobs)
            jobs[job.pid] = job
    finally:
        srv.close()
        for job in jobs.values():  # only after an error of the server itself: stop its workers
            job.kill()
        with _locked(path) as lock:
            _remove_files(path, lock, socket_ino)


#: Environment variable that switches the job server off ("0") for shell jobs; the Snakefile sets it from the
#: config key job_server (an environment variable, not a rule param: where a job runs does not change its result,
#: so switching it must not rerun finished jobs).
USE_SERVER_VAR = "BSRBENCH_JOB_SERVER"


def configure_shell_jobs(use_server=True):
    """Prepare this process's environment, which Snakemake's shell jobs inherit, for ``python -m bsrbench.jobserver
    job``: this interpreter's directory first on ``PATH`` (so that ``python`` is the interpreter running Snakemake;
    a conda deployment activates its own environment inside the job, which then comes first), and
    :data:`USE_SERVER_VAR` set from the config key ``job_server``."""
    os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")
    os.environ[USE_SERVER_VAR] = "1" if use_server else "0"


def main(argv=None):
    """``python -m bsrbench.jobserver SOCKET`` serves; ``... job TARGET --threads T --log LOG JSON`` runs a job."""
    import argparse
    import json

    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] != ["job"]:
        if not argv or argv[0].startswith("-"):
            print(
                "usage: python -m bsrbench.jobserver SOCKET [MODULE ...]  serve jobs on the Unix socket SOCKET,\n"
                "                                                         the job modules MODULE preloaded\n"
                "       python -m bsrbench.jobserver job --help           run one job (the study's rules do this)",
                file=sys.stderr,
            )
            raise SystemExit(0 if argv in (["-h"], ["--help"]) else 2)
        serve(argv[0], preload=argv[1:])
        return
    ap = argparse.ArgumentParser(prog="python -m bsrbench.jobserver job")
    ap.add_argument("target", help="module:function of bsrbench.jobs")
    ap.add_argument("job", help="the job's input, output and wildcards as JSON (job_params)")
    ap.add_argument("--settings", default="{}", help="the job's params as JSON (job_settings)")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--log", action="append", default=[])
    args = ap.parse_args(argv[1:])
    spec, params = json.loads(args.job), json.loads(args.settings)
    use_server = os.environ.get(USE_SERVER_VAR, "1") != "0"
    try:
        if "block" in spec:
            run_block(
                args.target,
                spec["block"],
                params=params,
                threads=args.threads,
                log=args.log,
                use_server=use_server,
            )
        else:
            job = dict(spec, params=params, threads=args.threads, log=args.log)
            run(args.target, job, use_server=use_server)
    except KeyboardInterrupt:
        # Ctrl-C reaches every job of the terminal's process group: Snakemake reports the interrupted jobs and
        # bin/study how to resume, so a traceback per running job would only bury that line
        raise SystemExit(130) from None


if __name__ == "__main__":
    main()
