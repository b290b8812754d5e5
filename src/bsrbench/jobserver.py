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
  log (the log only when empty or holding only warnings, which the server writes as one marked line each: any
  other line records a server failure, and the log is kept).
- Every request carries a fingerprint of the package's source files (paths, sizes, mtimes) and of the
  interpreter. A server started from other code answers "stale" and exits, and the job starts a fresh one,
  so an edited model never runs with old code.
- Each job is one fork (the worker); the server relays its result and watches the client's connection: if the
  client dies (Snakemake interrupted), the worker is killed. Outputs are written atomically, so nothing half-written
  is left.
- Threads: the child limits numba and BLAS to the job's ``threads``.
- What a client can ask for: any process of this user may connect, and it can have the server run only the
  study's job functions (:data:`JOB_TARGETS`; :func:`check_target` is the one check, of the server and of the
  client alike) on a job spec whose every field is checked for type, range and length (:func:`_check_request`,
  :func:`_check_job`). Such a job reads and writes the files its spec names, in the directory the request names,
  with the estimator its settings name (which :mod:`bsrbench.estimators` accepts only as a regressor class):
  nothing a process of this user could not do itself.
- Messages are plain JSON, never pickles, each prefixed with its length (8 bytes): a length over
  :data:`MAX_FRAME` (4 MiB) is refused before anything more is read, and nesting deeper than :data:`MAX_DEPTH`
  (32) before the JSON parser sees it (:func:`_decode`). A malformed request gets an error reply (one line
  saying why) and the server serves on.
- Deadlines: the server reads every request in its event loop and never waits on one client: a client gets
  ``BSRBENCH_JOBSERVER_REQUEST_TIMEOUT`` seconds (default 10) for its whole request, and as long again to take a
  reply, else its connection is closed. A job's error message in the reply is cut to 64 KiB (its log has all
  of it). The client gives the server ``BSRBENCH_JOBSERVER_TIMEOUT`` seconds (default 30) to take its request
  and answer "accepted" (the pids of the worker it forked and of the server); the job then runs as long as it
  needs, bounded only by its worker being alive: once the worker has ended, the server has that long again to
  relay its result (:func:`_await_result`). A client that gets no valid answer in time runs its job in-process;
  closing its connection kills a worker the server starts late.
- Only this user: the socket, lock and log live in a directory private to the user (:func:`runtime_dir`,
  refused if another user owns it or may enter it, or if others may write to its parent and it has no sticky
  bit, so that they could replace the directory). The directory is checked through a descriptor opened once,
  and the server binds its socket, and everyone opens the lock and log, relative to that descriptor (never
  through a symbolic link, and only regular files of this user with one link), so that a directory swapped or a
  link planted after the check redirects nothing (:class:`_Files`). Client and server check each other's uid on
  the socket (``SO_PEERCRED``) and close a foreign peer's connection unread.
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
import re
import reprlib
import select
import signal
import socket
import stat
import struct
import sys
import time
import warnings
from pathlib import Path

#: The server exits after this long without a job (a fallback: the run's end stops it, see the module docstring).
IDLE_SECONDS = 120.0
#: Environment variable holding the pid of the Snakemake process whose run the jobs belong to.
OWNER_VAR = "BSRBENCH_JOBSERVER_OWNER"
#: How long a job waits for a server it started to listen.
START_TIMEOUT = 60.0
#: Environment variable: seconds a client gives the server to take its request and answer "accepted", and, once
#: the job's worker has ended, to relay its result (default :data:`CLIENT_TIMEOUT`); then it runs the job itself.
TIMEOUT_VAR = "BSRBENCH_JOBSERVER_TIMEOUT"
CLIENT_TIMEOUT = 30.0
#: Environment variable: seconds the server gives a client to send its whole request, and to take a reply
#: (default :data:`REQUEST_TIMEOUT`).
REQUEST_TIMEOUT_VAR = "BSRBENCH_JOBSERVER_REQUEST_TIMEOUT"
REQUEST_TIMEOUT = 10.0
#: Environment variable naming the server's socket, as given, instead of one in :func:`runtime_dir`.
SOCKET_VAR = "BSRBENCH_JOBSERVER_SOCKET"
_PKG = Path(__file__).resolve().parent
#: Environment variables that set the thread counts of numba and of the BLAS/OpenMP libraries.
_THREAD_VARS = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


# ------------------------------------------------------------------------------------------------- framing
#: Largest message accepted, in bytes (a job spec or a reply is a few kB): a longer announced length is refused
#: before anything more is read.
MAX_FRAME = 4 << 20
#: Deepest nesting of lists and objects accepted in a message (a job request nests 4 deep).
MAX_DEPTH = 32
#: Longest job error message relayed to a client, in characters (the job's log has all of it).
_MAX_DETAIL = 1 << 16
_HEADER = struct.Struct("!Q")


class ProtocolError(OSError):
    """A peer sent something that is not a message of this protocol (or a message could not be encoded)."""


class PeerRefused(OSError):
    """The process at the other end of the socket runs as another user (or its user cannot be checked)."""


class UnsafeDirectory(OSError):
    """The job server's directory, or its lock or log file, is not safe: not private to this user, or open to
    replacement by other users."""


def _encode(obj):
    """``obj`` as a message: the length of its JSON (8 bytes, big-endian), then the JSON."""
    try:
        data = json.dumps(obj).encode()
    except (TypeError, ValueError) as exc:
        raise ProtocolError(f"message not JSON-serializable: {exc}") from None
    if len(data) > MAX_FRAME:
        raise ProtocolError(f"a message of {len(data)} bytes, more than the limit of {MAX_FRAME}")
    return _HEADER.pack(len(data)) + data


#: An escape in a JSON string (a backslash and the character after it); runs of what is not a bracket; objects'
#: brackets as lists' (nesting counts the same).
_ESCAPE = re.compile(r"\\.", re.DOTALL)
_NOT_BRACKETS = re.compile(r"[^\[\]{}]+")
_ONE_KIND = str.maketrans("{}", "[]")


def _too_deep(text):
    """True if the JSON ``text`` nests lists and objects more than :data:`MAX_DEPTH` deep, or if its brackets
    outside strings do not pair up (then it is not JSON either). Found with string operations, without recursion,
    so that the parser never recurses deeper than that: at most :data:`MAX_DEPTH` passes over the brackets."""
    if "\\" in text:
        text = _ESCAPE.sub("", text)
    outside = "".join(text.split('"')[::2])  # what is outside strings
    brackets = _NOT_BRACKETS.sub("", outside).translate(_ONE_KIND)
    if len(brackets) <= MAX_DEPTH:
        return False
    # each pass removes the innermost pairs: d levels of nesting empty in d passes
    for _ in range(MAX_DEPTH):
        if "[" * (MAX_DEPTH + 1) in brackets:  # found at once for most deep texts
            return True
        brackets, before = brackets.replace("[]", ""), brackets
        if not brackets:
            return False
        if len(brackets) == len(before):  # unpaired brackets
            return True
    return True


def _decode(data):
    """The JSON message ``data`` (bytes) as plain data (dicts, lists, strings, numbers), whatever the peer sent;
    ProtocolError if it is not UTF-8 JSON nested at most :data:`MAX_DEPTH` deep."""
    try:
        text = data.decode()
    except UnicodeDecodeError:
        raise ProtocolError("a message that is not JSON") from None
    if _too_deep(text):
        raise ProtocolError(f"a message nested more than {MAX_DEPTH} deep, or not JSON")
    try:
        return json.loads(text)
    except (ValueError, RecursionError):
        raise ProtocolError("a message that is not JSON") from None


class _Frame:
    """One message being received, in pieces: its length, refused (ProtocolError) as soon as it is known to be over
    :data:`MAX_FRAME`, before anything of that size is read or allocated; then its bytes."""

    __slots__ = ("head", "body", "size")

    def __init__(self):
        self.head, self.body, self.size = b"", bytearray(), None

    def wanted(self):
        """How many bytes to read next: never more than this message has left."""
        if self.size is None:
            return _HEADER.size - len(self.head)
        return min(self.size - len(self.body), 1 << 16)

    def feed(self, chunk):
        """Add ``chunk`` (at most :meth:`wanted` bytes); True once the message is complete."""
        if self.size is None:
            self.head += chunk
            if len(self.head) < _HEADER.size:
                return False
            (size,) = _HEADER.unpack(self.head)
            if size > MAX_FRAME:
                raise ProtocolError(
                    f"a message of {size} bytes announced, more than the limit of {MAX_FRAME}"
                )
            self.size = size
        else:
            self.body += chunk
        return len(self.body) == self.size

    def message(self):
        """The complete message, decoded (:func:`_decode`)."""
        return _decode(bytes(self.body))


def _left(deadline):
    """Seconds until ``deadline`` (a time.monotonic()); TimeoutError once it has passed."""
    left = deadline - time.monotonic()
    if left <= 0:
        raise TimeoutError("deadline passed")
    return left


def _send(sock, obj, deadline=None):
    """Send ``obj`` as a message (:func:`_encode`), all of it before ``deadline`` (TimeoutError) if one is given."""
    data = memoryview(_encode(obj))
    while data:
        if deadline is not None:
            sock.settimeout(_left(deadline))
        data = data[sock.send(data) :]


def _recv(sock, deadline=None):
    """Receive one message of :func:`_send`, all of it before ``deadline`` (TimeoutError) if one is given: plain
    data, whatever the peer sent; ProtocolError if it is not a message, EOFError if the peer closed first."""
    frame = _Frame()
    while True:
        if deadline is not None:
            sock.settimeout(_left(deadline))
        chunk = sock.recv(frame.wanted())
        if not chunk:
            raise EOFError("connection closed")
        if frame.feed(chunk):
            return frame.message()


#: Largest process id on Linux (PID_MAX_LIMIT); longest path (PATH_MAX).
_PID_MAX = 1 << 22
_MAX_PATH = 4096


def _is_pid(value):
    return type(value) is int and 0 < value <= _PID_MAX


def _reply(status, detail=None, **fields):
    return {"status": status, "detail": detail, **fields}


_STATUSES = ("ok", "error", "stale", "bye", "accepted")


def _check_reply(reply):
    """``reply`` if it is a server's reply (an "accepted" one with the pids of the worker and of the server);
    ProtocolError if not."""
    if not (
        isinstance(reply, dict)
        and reply.get("status") in _STATUSES
        and isinstance(reply.get("detail"), (str, type(None)))
        and (
            reply["status"] != "accepted"
            or (_is_pid(reply.get("worker")) and _is_pid(reply.get("server")))
        )
    ):
        raise ProtocolError("a reply that is not a job server's")
    return reply


def _peer(sock):
    """(pid, uid) of the process at the other end of the Unix socket ``sock`` (for a client: the process that
    listens; for the server: the process that connected), from the kernel (``SO_PEERCRED``)."""
    if not hasattr(socket, "SO_PEERCRED"):
        raise PeerRefused("this platform has no SO_PEERCRED to check the job server's user")
    ucred = struct.Struct("3i")  # struct ucred: pid, uid, gid
    pid, uid, _ = ucred.unpack(sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, ucred.size))
    return pid, uid


# --------------------------------------------------------------------------------------------- identities
def fingerprint():
    """Hash of the interpreter and of every source file of the package (path, size, mtime)."""
    h = hashlib.sha256(f"{sys.executable}|{sys.version}".encode())
    for path in sorted(_PKG.rglob("*.py")):
        st = path.stat()
        h.update(f"{path}|{st.st_size}|{st.st_mtime_ns}".encode())
    return h.hexdigest()


def _runtime_path():
    """Where :func:`runtime_dir` is (nothing created or checked)."""
    base = os.environ.get("XDG_RUNTIME_DIR")
    if base:
        return Path(base) / "bsrbench"
    return Path(os.environ.get("TMPDIR") or "/tmp") / f"bsrbench-{os.geteuid()}"


def runtime_dir():
    """This user's private directory for the server's socket, lock and log, created if absent:
    ``$XDG_RUNTIME_DIR/bsrbench``, else ``$TMPDIR/bsrbench-<uid>`` (``/tmp`` without ``TMPDIR``).

    Like ssh-agent's and tmux's, it must be a real directory (not a link) owned by this user with no access for
    group or others: otherwise another user could put a socket of theirs where the jobs connect, or read the
    log; and others must not be able to replace it (its parent not writable by them, or with the sticky bit, as
    /tmp). Raises :class:`UnsafeDirectory` (naming the path, what was found, and what is expected)."""
    path = _runtime_path()
    os.close(_open_dir(path, private=True, create=True))
    return path


def _kind(mode, other):
    """What the file of ``mode`` is, in words (``other`` if none of these)."""
    kinds = (
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISLNK, "a symbolic link"),
        (stat.S_ISREG, "a file"),
        (stat.S_ISSOCK, "a socket"),
    )
    return next((k for test, k in kinds if test(mode)), other)


def _replaceable(st):
    """True if users other than the owner may replace the entries of the directory ``st``: it is writable by
    others and has no sticky bit."""
    return bool(st.st_mode & stat.S_IWOTH) and not st.st_mode & stat.S_ISVTX


#: A directory opened for its descriptor only (no read permission needed, where the platform has O_PATH).
_DIR_FLAGS = getattr(os, "O_PATH", os.O_RDONLY) | os.O_DIRECTORY | os.O_CLOEXEC


def _open_dir(path, *, private, create=False):
    """A descriptor of the directory ``path``, checked through the descriptor itself, so that what was checked is
    what is used, whatever becomes of the path.

    ``private`` (:func:`runtime_dir`): a real directory (not a link) owned by this user with no access for group
    or others, in a parent that others cannot replace it in; ``create``: made with mode 0700 if absent.
    Otherwise (a socket given by :data:`SOCKET_VAR`): a directory owned by this user or root in which others
    cannot replace entries. Raises :class:`UnsafeDirectory` (one line: the path, what was found, what is
    expected)."""
    path, uid = Path(path), os.geteuid()
    if private:
        parent = os.stat(path.parent)
        if _replaceable(parent):
            raise UnsafeDirectory(
                f"unsafe job server directory {path}: its parent {path.parent} has mode "
                f"{stat.S_IMODE(parent.st_mode):04o} (others may write to it and it has no sticky bit, so another "
                "user could replace the directory); expected a parent that others cannot write to, or with the "
                "sticky bit (as /tmp, mode 1777)"
            )
    if create:
        try:
            os.mkdir(path, 0o700)
            # the umask can only remove bits of 0700; this restores the owner's (a umask of 0o777 removes them)
            try:
                os.chmod(path, 0o700, follow_symlinks=False)
            except NotImplementedError:
                pass  # a symbolic link by now (refused below), or no such call here
        except FileExistsError:
            pass
    try:
        fd = os.open(path, _DIR_FLAGS | (os.O_NOFOLLOW if private else 0))
    except OSError as exc:
        if exc.errno not in (errno.ELOOP, errno.ENOTDIR):
            raise  # else a link, or not a directory: say what it is
        fd, st = None, os.lstat(path)
    else:
        st = os.fstat(fd)
    if private:
        ok = st.st_uid == uid and not st.st_mode & 0o077
        expected = f"a directory owned by uid {uid} (this user) with mode 0700 (no access for group or others)"
    else:
        ok = st.st_uid in (uid, 0) and not _replaceable(st)
        expected = (
            f"a directory owned by uid {uid} (this user) or root that others cannot write to, or with the "
            "sticky bit (as /tmp, mode 1777)"
        )
    if fd is None or not ok:
        if fd is not None:
            os.close(fd)
        raise UnsafeDirectory(
            f"unsafe job server directory {path}: {_kind(st.st_mode, 'not a directory')} owned by uid "
            f"{st.st_uid} with mode {stat.S_IMODE(st.st_mode):04o}; expected {expected}"
        )
    return fd


def socket_path(cwd=None):
    """The server's socket in :func:`runtime_dir`, one per environment and working directory (``cwd``, default the
    current one); the server's lock and log files are this path + ``.lock`` and ``.log``.
    :data:`SOCKET_VAR` overrides it, as given (benchmarks run servers of other revisions there)."""
    if os.environ.get(SOCKET_VAR):
        return Path(os.environ[SOCKET_VAR])
    cwd = Path(cwd or os.getcwd()).resolve()
    key = hashlib.sha256(f"{sys.prefix}|{_PKG}|{cwd}".encode()).hexdigest()[:16]
    return runtime_dir() / f"jobserver-{key}.sock"


#: How the server writes a warning into its log: one line, marked, so that a log of warnings only is not taken
#: for a server failure (:func:`_only_warnings`).
_WARNING = "bsrbench.jobserver: warning: "
#: The warnings module's own showwarning, which a worker restores (its warnings go to the job's log as usual).
_SHOWWARNING = warnings.showwarning


def _log_warning(message, category, filename, lineno, file=None, line=None):
    """The server's ``warnings.showwarning``: one marked line in its log."""
    text = " ".join(str(message).split())
    print(
        f"{_WARNING}{category.__name__}: {text} ({filename}:{lineno})", file=sys.stderr, flush=True
    )


def _only_warnings(log):
    """True if the server log ``log`` (a binary file, at most 1 MiB read) holds nothing but warnings
    (:func:`_log_warning`)."""
    data = log.read(1 << 20)
    if log.read(1):
        return False
    lines = data.decode(errors="replace").splitlines()
    return all(line.startswith(_WARNING) for line in lines if line.strip())


class _Files:
    """The server's socket, lock and log (the socket's path + ``.lock``, ``.log``), reached through a descriptor
    of their directory that was checked when opened (:func:`_open_dir`): a directory swapped or a link planted
    after the check redirects nothing. A context manager (it closes the descriptor)."""

    def __init__(self, path):
        self.path = Path(path)
        self.name = self.path.name
        self.dir_fd = _open_dir(self.path.parent, private=self.path.parent == _runtime_path())

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        os.close(self.dir_fd)

    def stat(self, suffix=""):
        """The status of the socket, or of its ``.lock`` or ``.log`` (``suffix``), not following a link."""
        return os.stat(self.name + suffix, dir_fd=self.dir_fd, follow_symlinks=False)

    def unlink(self, suffix=""):
        os.unlink(self.name + suffix, dir_fd=self.dir_fd)

    def open(self, suffix, flags):
        """A descriptor of the ``.lock`` or ``.log`` file (``suffix``): created if absent (O_EXCL), never opened
        through a symbolic link (O_NOFOLLOW), and refused (:class:`UnsafeDirectory`) unless it is a regular file of
        this user with one link (not a hard link to a file elsewhere)."""
        name, uid = self.name + suffix, os.geteuid()
        # O_NONBLOCK: a FIFO put in the file's place must not block the open
        flags |= os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
        try:
            fd = os.open(name, flags | os.O_CREAT | os.O_EXCL, 0o600, dir_fd=self.dir_fd)
        except FileExistsError:
            try:
                fd = os.open(name, flags, dir_fd=self.dir_fd)
            except OSError as exc:
                if exc.errno != errno.ELOOP:
                    raise
                fd = None
        st = self.stat(suffix) if fd is None else os.fstat(fd)
        if fd is None or not (stat.S_ISREG(st.st_mode) and st.st_uid == uid and st.st_nlink == 1):
            if fd is not None:
                os.close(fd)
            links = f" with {st.st_nlink} links" if stat.S_ISREG(st.st_mode) else ""
            raise UnsafeDirectory(
                f"unsafe job server file {self.path}{suffix}: {_kind(st.st_mode, 'a special file')} owned by "
                f"uid {st.st_uid}{links}; expected a regular file owned by uid {uid} (this user) with one link"
            )
        os.set_blocking(fd, True)
        return fd

    def lock(self, timeout=START_TIMEOUT + 30):
        """The lock file's descriptor, locked (``flock``): a client holds it while it starts a server, an exiting
        server while it removes its files. Retried if an exiting server unlinked the file while we waited for it;
        TimeoutError if it stays taken for ``timeout`` seconds (by a process that is stuck)."""
        deadline = time.monotonic() + timeout
        while True:
            fd = self.open(".lock", os.O_RDWR)
            try:
                while True:
                    try:
                        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                        break
                    except BlockingIOError:
                        if time.monotonic() > deadline:
                            raise TimeoutError(
                                f"the job server's lock {self.path}.lock stayed taken for {timeout:.0f} s"
                            ) from None
                        time.sleep(0.05)
                if self.stat(".lock").st_ino == os.fstat(fd).st_ino:
                    return fd
            except FileNotFoundError:
                pass
            except BaseException:
                os.close(fd)
                raise
            os.close(fd)

    def remove(self, lock, socket_ino=None):
        """Remove the socket (if ``socket_ino`` is None or it is still that inode), the log if it is empty or holds
        only warnings, and the lock (while ``lock``, its descriptor, holds it, so that no client is starting a
        server meanwhile). A kept log is named on stderr, unless stderr is that log (a server's)."""
        try:
            st = self.stat()
            if stat.S_ISSOCK(st.st_mode) and socket_ino in (None, st.st_ino):
                self.unlink()
        except FileNotFoundError:
            pass
        try:
            fd = os.open(
                self.name + ".log",
                os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC,
                dir_fd=self.dir_fd,
            )
        except OSError:  # none, or a link (not ours to remove)
            fd = None
        if fd is not None:
            with open(fd, "rb") as log:
                st = os.fstat(fd)
                try:
                    if not stat.S_ISREG(st.st_mode):
                        pass
                    elif st.st_size == 0 or _only_warnings(log):
                        if self.stat(".log").st_ino == st.st_ino:
                            self.unlink(".log")
                    elif not os.path.samestat(
                        os.fstat(2), st
                    ):  # not into the log (a server's stderr)
                        kept = f"bsrbench.jobserver: the server wrote to {self.path}.log (kept)"
                        print(kept, file=sys.stderr)
                except FileNotFoundError:
                    pass
        try:
            if self.stat(".lock").st_ino == os.fstat(lock).st_ino:
                self.unlink(".lock")
        except FileNotFoundError:
            pass


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
    that runs ``python -P -m bsrbench.jobserver job TARGET --threads {threads} --log {log} JOB --settings SETTINGS``
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


#: The job functions (``module:function``) a job may name, and so all that the job server runs: the targets of the
#: workflow's rules (workflow/rules/fit.smk) and :func:`ping`, the no-op job of the tests and of
#: benchmarks/bench_job_floor.py.
JOB_TARGETS = (
    "bsrbench.jobs:cv",
    "bsrbench.jobs:fit",
    "bsrbench.jobs:fit_chain",
    "bsrbench.jobs:pool",
    "bsrbench.jobserver:ping",
)


class JobRefused(ValueError):
    """A job names a target that is not one of :data:`JOB_TARGETS`."""


def _shown(value):
    """``value`` for a one-line message: its repr, shortened."""
    return reprlib.repr(value)


def check_target(target):
    """``target`` if it is one of :data:`JOB_TARGETS`, else :class:`JobRefused` (one line): the one check of the
    server (before it forks a worker) and of the client (before it sends or runs a job)."""
    if target not in JOB_TARGETS:
        raise JobRefused(
            f"job target {_shown(target)} is not one of the study's job functions ({', '.join(JOB_TARGETS)})"
        )
    return target


def job_function(target):
    """The function of the job target ``target`` (:func:`check_target`), imported."""
    module, name = check_target(target).split(":")
    return getattr(importlib.import_module(module), name)


def _refused(exc, log):
    """The SystemExit of a refused job target (:class:`JobRefused` ``exc``), its line also in the job's ``log``
    (where the rule's error message points)."""
    line = f"bsrbench.jobserver: refused: {exc}"
    if log:
        try:
            with open(log[0], "a") as f:
                print(line, file=f)
        except OSError:
            pass
    return SystemExit(line)


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
    """Run the job function ``target`` (:func:`job_function`: one of :data:`JOB_TARGETS`, else JobRefused) on
    ``job`` in this process, log to the job's log file."""
    check_target(target)
    threads = str(job.get("threads", 1))
    for var in _THREAD_VARS:
        os.environ[var] = threads  # before numba and BLAS are imported
    log = job.get("log") or []
    if log:
        sys.stderr = open(log[0], "a" if job.get("log_append") else "w", buffering=1)
    job_function(target)(job)


#: Environment variables that batch systems set inside a submitted job: such a job runs on a compute node, where
#: a job server would only add a start-up per job, so it runs in-process whatever the config key job_server says
#: (a command-line ``--config`` replaces the SLURM profile's own ``job_server=False``).
_BATCH_JOB_VARS = ("SLURM_JOB_ID", "PBS_JOBID", "LSB_JOBID")


def in_batch_job():
    """True inside a job submitted to SLURM, PBS/Torque or LSF (see :data:`_BATCH_JOB_VARS`)."""
    return any(os.environ.get(var) for var in _BATCH_JOB_VARS)


def run(target, job, *, use_server=True):
    """Run a job: in a fork of the warm server if possible, else in this process (always in this process inside a
    batch-system job, :func:`in_batch_job`). A target not in :data:`JOB_TARGETS` is refused (SystemExit, one line,
    also written to the job's log)."""
    try:
        check_target(target)
    except JobRefused as exc:
        raise _refused(exc, job.get("log")) from None
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
    (SystemExit); Snakemake then removes the outputs of the whole block, and reruns it whole. A target not in
    :data:`JOB_TARGETS` is refused before any step, as :func:`run` refuses it."""
    import traceback

    if log:
        open(log[0], "w").close()
    try:
        check_target(target)
    except JobRefused as exc:
        raise _refused(exc, log) from None
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


def _seconds(var, default):
    """The positive number of seconds in the environment variable ``var``, else ``default``."""
    try:
        value = float(os.environ.get(var, ""))
    except ValueError:
        return default
    return value if 0 < value < float("inf") else default


#: What connecting raises when no server listens (no socket, or no process behind it): then a job starts one.
_NO_SERVER = (FileNotFoundError, ConnectionRefusedError)


def _connect(path, timeout=None):
    """A connection to the server at ``path`` (within ``timeout`` seconds, if given); :class:`PeerRefused` (closed
    unwritten) if it runs as another user; one of :data:`_NO_SERVER` if none listens."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.settimeout(timeout)
        sock.connect(str(path))
        _, uid = _peer(sock)
    except TimeoutError:  # it listens, but takes no connection (its backlog is full)
        sock.close()
        raise TimeoutError(
            f"the job server at {path} took no connection within {timeout:g} s"
        ) from None
    except OSError:
        sock.close()
        raise
    if uid != os.geteuid():
        sock.close()
        raise PeerRefused(
            f"refused the server at {path}: it runs as uid {uid}, not as this user (uid {os.geteuid()})"
        )
    return sock


def _start_server(path, preload=(), timeout=None):
    """Start a server (preloading the modules ``preload``) unless another job is starting one; wait until it
    listens (at most :data:`START_TIMEOUT` s, or until it exits); a connection to it (``timeout``: of
    :func:`_connect`)."""
    import subprocess  # here, not at the top: a job's client never starts a server once one runs

    with _Files(path) as files:
        lock = files.lock()
        try:
            try:  # never replace a server that listens, even a foreign or a stuck one: the job runs in-process
                return _connect(path, timeout)
            except _NO_SERVER:
                pass
            env = dict(os.environ)
            for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
                env[var] = (
                    "1"  # no BLAS thread pools in the process that forks; children may raise them
                )
            env["NUMBA_NUM_THREADS"] = str(os.cpu_count() or 1)
            log = files.open(".log", os.O_WRONLY | os.O_APPEND)
            try:
                server = subprocess.Popen(
                    [sys.executable, "-P", "-m", "bsrbench.jobserver", str(path), *preload],
                    stdin=subprocess.DEVNULL,
                    stdout=subprocess.DEVNULL,
                    stderr=log,
                    start_new_session=True,
                    env=env,
                )
            finally:
                os.close(log)
            deadline = time.monotonic() + START_TIMEOUT
            while time.monotonic() < deadline:
                try:
                    return _connect(path, timeout)
                except PeerRefused:
                    raise
                except OSError:
                    if server.poll() is not None:
                        raise OSError(
                            f"job server at {path} exited with code {server.returncode} before it listened "
                            f"(log: {path}.log)"
                        ) from None
                    time.sleep(0.05)
            raise TimeoutError(
                f"job server at {path} did not start within {START_TIMEOUT:.0f} s (log: {path}.log)"
            )
        finally:
            os.close(lock)


def _run_remote(target, job):
    """(status, detail) of ``job`` run by the server (started if need be): "ok", or "error" and why.
    TimeoutError, PeerRefused, UnsafeDirectory or another OSError if the server cannot be used."""
    timeout = _seconds(TIMEOUT_VAR, CLIENT_TIMEOUT)
    path = socket_path()
    request = {
        "target": target,
        "job": job,
        "fingerprint": fingerprint(),
        "cwd": os.getcwd(),
        "owner": _owner(),
        "ack": True,
    }
    for _ in range(2):
        try:
            sock = _connect(path, timeout)
        except _NO_SERVER:
            sock = _start_server(path, preload=[target.split(":")[0]], timeout=timeout)
        with sock:
            reply = _exchange(sock, request, path, timeout)
        if reply["status"] != "stale":
            return reply["status"], reply["detail"]
        # the server ran other code: it is shutting down; wait for its socket to go, then start a new one
        deadline = time.monotonic() + 10
        while path.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
    raise OSError(errno.EAGAIN, "job server stayed stale")


def _exchange(sock, request, path, timeout):
    """Send ``request`` and return the server's reply: its answer within ``timeout`` seconds, and for an
    "accepted" one the job's result, however long the job runs (:func:`_await_result`)."""
    deadline = time.monotonic() + timeout
    try:
        _send(sock, request, deadline)
        reply = _check_reply(_recv(sock, deadline))
    except TimeoutError:
        raise TimeoutError(
            f"no answer from the job server at {path} within {timeout:g} s"
        ) from None
    if reply["status"] == "accepted":
        reply = _await_result(sock, reply, path, timeout)
    return reply


def _await_result(sock, accepted, path, timeout):
    """The result ("ok" or "error") that the server sends once the worker of its ``accepted`` reply has ended.

    No deadline while the worker runs (a chain may compute for half an hour); once it has ended (gone, or a zombie
    that the server has not reaped), the server has ``timeout`` seconds to relay the result. The worker is
    watched by its pid only if the server's pid in the reply is the one the kernel gives for the socket's peer
    (the same pid namespace); otherwise the wait ends with the connection (the kernel kills the worker if the
    server dies)."""
    worker = accepted["worker"]
    watch = accepted["server"] == _peer(sock)[0]
    ended = None
    while True:
        readable, _, _ = select.select([sock], [], [], 1.0)
        if readable:
            try:
                reply = _check_reply(_recv(sock, time.monotonic() + timeout))
            except TimeoutError:
                raise TimeoutError(
                    f"no complete result from the job server at {path} within {timeout:g} s"
                ) from None
            if reply["status"] not in ("ok", "error"):
                raise ProtocolError("a reply that is not a job server's")
            return reply
        if watch and not _running(worker):
            ended = ended or time.monotonic()
            if time.monotonic() - ended > timeout:
                raise TimeoutError(
                    f"the job server at {path} did not relay the result of its worker {worker} within "
                    f"{timeout:g} s of the worker's end"
                )


def _owner():
    """The pid in :data:`OWNER_VAR`, or None."""
    try:
        pid = int(os.environ.get(OWNER_VAR, ""))
    except ValueError:
        return None
    return pid if _is_pid(pid) else None


def shutdown(path=None, timeout=30.0):
    """Stop the job server of this working directory (or at ``path``) and wait until its files are gone.

    Called by the Snakefile's ``onsuccess`` and ``onerror`` handlers. Without a listening server, removes what a
    killed one left (socket, lock, empty log). Returns True if a server was stopped; never raises.
    """
    try:
        path = Path(path) if path else socket_path()
        try:  # a foreign server is not ours to stop or to remove, nor is a stuck one to remove
            sock = _connect(path, timeout)
        except _NO_SERVER:
            with _Files(path) as files:
                lock = files.lock()  # no server: tidy up, unless one starts right now
                try:
                    try:
                        _connect(path, timeout).close()
                    except _NO_SERVER:
                        files.remove(lock)
                finally:
                    os.close(lock)
            return False
        with sock:
            deadline = time.monotonic() + timeout
            _send(sock, {"shutdown": True}, deadline)
            try:
                _recv(sock, deadline)
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


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _running(pid):
    """True while the process ``pid`` runs: not gone, and not a zombie (exited, not yet reaped by its parent)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            state = f.read().rpartition(b")")[2].split()[:1]
    except FileNotFoundError:
        return not os.path.exists("/proc/self/stat") and _alive(
            pid
        )  # no /proc here: alive is all we know
    except OSError:
        return _alive(pid)
    return state not in ([b"Z"], [b"X"])


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
def _clip(text, limit=_MAX_DETAIL):
    """``text`` cut to about ``limit`` characters: its start and its end (where a traceback names the error)."""
    if text is None or len(text) <= limit:
        return text
    head = limit // 4
    return (
        f"{text[:head]}\n[... {len(text) - limit} characters cut: the job's log has them ...]\n"
        f"{text[len(text) - (limit - head) :]}"
    )


def _worker(request, conn, result_w, inherited):
    """The forked worker: the job's directory, log and threads, then the job itself; its result goes to the pipe
    ``result_w``. ``inherited``: the server's descriptors (listening socket, directory, other clients' connections,
    other jobs' pipes)."""
    import traceback

    for fd in inherited:
        try:
            os.close(fd)
        except OSError:
            pass
    conn.close()
    # the job's warnings go to its log, as in a process of its own
    warnings.showwarning = _SHOWWARNING
    status, detail = "ok", None
    try:
        os.chdir(request["cwd"])
    except OSError as exc:
        # gone since the server's check (_check_cwd), or not ours to enter: one line to the client, and nothing
        # into the server's log (its stderr, still ours here), which a traceback would keep as a server failure
        status = "error"
        detail = (
            f"refused a request: field 'cwd' is {_shown_path(request['cwd'])}, which cannot be entered "
            f"({exc.strerror or exc}); expected an existing directory"
        )
    else:
        try:
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
            job_function(request["target"])(job)
        except BaseException:
            detail = traceback.format_exc()
            status = "error"
            print(detail, file=sys.stderr)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        data = memoryview(json.dumps(_reply(status, _clip(detail))).encode())
        while data:
            data = data[os.write(result_w, data) :]
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
        self.pid, self.conn, self.result_r, self.chunks, self.size = pid, conn, result_r, [], 0
        # the job's log file (absolute): a worker that died says nothing there itself
        self.log = log

    def relay(self):
        """Read the worker's result pipe; at its end, reap the worker and return its result (None until then). The
        connection is then the caller's, to send the result on."""
        data = os.read(self.result_r, 1 << 16)
        if data:
            self.size += len(data)
            if (
                self.size <= MAX_FRAME
            ):  # a worker's result is a few fields and at most _MAX_DETAIL characters
                self.chunks.append(data)
            return None
        _, status = os.waitpid(self.pid, 0)
        os.close(self.result_r)
        try:
            result = _check_reply(json.loads(b"".join(self.chunks)))
        except (ValueError, ProtocolError):
            result = _reply("error", f"worker {_describe_exit(status)} without a result")
            self._note(result["detail"])
        return result

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
        os.close(self.result_r)
        self.conn.close()


class _Client:
    """A connection the server reads a request from, or writes a reply to and then closes, until ``deadline`` (of
    time.monotonic()). The socket does not block: the server never waits on one client, so a client that sends
    slowly, or does not read, holds up nothing but itself."""

    def __init__(self, sock, deadline):
        self.sock, self.deadline, self.frame, self.out = sock, deadline, _Frame(), None

    def read(self):
        """Read what has arrived: the :class:`_Frame` once complete, else None. BlockingIOError if nothing has
        arrived, EOFError if the client closed, ProtocolError if what it sends is not a message."""
        chunk = self.sock.recv(self.frame.wanted())
        if not chunk:
            raise EOFError("connection closed")
        return self.frame if self.frame.feed(chunk) else None

    def answer(self, reply, deadline):
        """Write ``reply`` from now on, until ``deadline``."""
        self.frame, self.out, self.deadline = None, memoryview(_encode(reply)), deadline

    def write(self):
        """Write what the socket takes of the reply; True once all of it is written."""
        self.out = self.out[self.sock.send(self.out) :]
        return not self.out


def _start_job(conn, request, inherited):
    """Fork the worker of ``request``, whose client is connected on ``conn``; tell the client that its job is
    accepted (the pids of the worker and of the server, :func:`_await_result`) if it asked so. The server then
    watches the worker's pipe and the client's connection (:class:`_Job`; None if the client could not be told).
    ``inherited``: the server's descriptors, which the worker closes."""
    result_r, result_w = os.pipe()
    server_pid = os.getpid()
    pid = os.fork()
    if pid == 0:
        _die_with_server(server_pid)
        os.close(result_r)
        _worker(request, conn, result_w, inherited)
    os.close(result_w)
    log = request["job"].get("log")
    log = log[0] if log else None
    job = _Job(pid, conn, result_r, log and os.path.join(request["cwd"], log))
    if request.get("ack"):
        accepted = _encode(_reply("accepted", worker=pid, server=server_pid))
        try:  # a few bytes into the socket's empty buffer: taken at once
            sent = conn.send(accepted)
        except OSError:
            sent = 0
        if sent != len(accepted):
            job.kill()
            return None
    return job


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


def _is_path(value):
    return isinstance(value, str) and 0 < len(value) <= _MAX_PATH and "\0" not in value


def _is_name(value):
    return isinstance(value, str) and len(value) <= 200


#: Fields of a job request (:func:`_run_remote`), the first four required: how each is checked, and what it must
#: be. A shutdown request is ``{"shutdown": true}``.
_REQUEST_FIELDS = {
    "target": (_is_name, "a string of at most 200 characters"),
    "job": (lambda v: isinstance(v, dict), "an object"),
    "fingerprint": (_is_name, "a string of at most 200 characters"),
    "cwd": (lambda v: _is_path(v) and os.path.isabs(v), "an absolute path"),
    "owner": (lambda v: v is None or _is_pid(v), f"a process id (1 to {_PID_MAX}) or null"),
    "ack": (lambda v: isinstance(v, bool), "true or false"),
}
#: Fields of a job spec (:mod:`bsrbench.jobs`), and the JSON type of each.
_JOB_FIELDS = {
    "input": dict,
    "output": dict,
    "params": dict,
    "wildcards": dict,
    "log": list,
    "log_append": bool,
    "threads": int,
}
_JSON_NAMES = {dict: "an object", list: "a list", bool: "true or false", int: "an integer"}
#: Longest string anywhere in a job spec; most threads a job may ask for.
_MAX_STRING = 1 << 16
_MAX_THREADS = 1024


def _check_request(request):
    """``request`` if it is a shutdown request, or a job request whose fields are of their type and range
    (:data:`_REQUEST_FIELDS`); ProtocolError (one line) if not. The target and the job spec's contents are checked
    after the fingerprint (:func:`check_target`, :func:`_check_job`): a client of other code gets "stale" whatever
    it asks for."""
    if not isinstance(request, dict):
        raise ProtocolError(f"a request that is not a JSON object: {_shown(request)}")
    if request.get("shutdown") is True and len(request) == 1:
        return request
    names = list(_REQUEST_FIELDS)
    if not set(names[:4]) <= set(request) <= set(names):
        raise ProtocolError(
            f"a request with fields {_shown(sorted(request))}; expected {', '.join(names[:4])} and "
            f"optionally {', '.join(names[4:])}"
        )
    for key, value in request.items():
        ok, expected = _REQUEST_FIELDS[key]
        if not ok(value):
            raise ProtocolError(f"{key} is {_shown(value)}; expected {expected}")
    return request


def _shown_path(path):
    """``path`` for a one-line message: its repr (escapes a newline), cut at 300 characters."""
    text = repr(path)
    return text if len(text) <= 300 else text[:297] + "..."


def _check_cwd(cwd):
    """``cwd`` (a request's working directory, an absolute path) if it is an existing directory; ProtocolError
    (one line) if not: the worker changes into it before anything else, and a failure there was a traceback."""
    if not os.path.isdir(cwd):
        what = "is not a directory" if os.path.lexists(cwd) else "does not exist"
        raise ProtocolError(
            f"field 'cwd' is {_shown_path(cwd)}, which {what}; expected an existing directory"
        )
    return cwd


def _check_job(job):
    """``job`` (a request's job spec) if its fields are those of :data:`_JOB_FIELDS`, each of its type, ``threads``
    from 1 to :data:`_MAX_THREADS`, ``log`` at most 8 paths, every string in it at most :data:`_MAX_STRING`
    characters and every integer within 64 bits; ProtocolError (one line) if not."""
    for key, value in job.items():
        kind = _JOB_FIELDS.get(key)
        if kind is None:
            raise ProtocolError(
                f"job field {_shown(key)} unknown; expected {', '.join(_JOB_FIELDS)}"
            )
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            raise ProtocolError(f"job field {key} is {_shown(value)}; expected {_JSON_NAMES[kind]}")
    threads = job.get("threads", 1)
    if not 1 <= threads <= _MAX_THREADS:
        raise ProtocolError(f"job field threads is {threads}; expected 1 to {_MAX_THREADS}")
    log = job.get("log", [])
    if len(log) > 8 or not all(_is_path(p) for p in log):
        raise ProtocolError(f"job field log is {_shown(log)}; expected a list of at most 8 paths")
    stack = [job]
    while stack:
        value = stack.pop()
        if isinstance(value, dict):
            stack.extend(value)
            stack.extend(value.values())
        elif isinstance(value, list):
            stack.extend(value)
        elif isinstance(value, str) and len(value) > _MAX_STRING:
            raise ProtocolError(
                f"a string of {len(value)} characters in the job, more than {_MAX_STRING}"
            )
        elif isinstance(value, int) and not -(1 << 63) <= value < 1 << 63:
            raise ProtocolError(f"an integer in the job outside 64 bits: {_shown(value)}")
    return job


#: Most connections the server reads requests from, or writes replies to, at once; more wait in the backlog.
_MAX_CLIENTS = 64


def serve(path, idle=IDLE_SECONDS, preload=(), request_timeout=None):
    """Import the job modules ``preload`` (:func:`_preload`), listen on ``path`` and fork a worker per request,
    relaying each worker's result to its client, until asked to shut down, until every Snakemake process it served
    for is gone, or until idle for ``idle`` seconds; then finish the running jobs and remove its files.

    One event loop (``poll``) reads requests, relays results and writes replies, never blocking on a client:
    each gets ``request_timeout`` seconds (default :data:`REQUEST_TIMEOUT_VAR`, else :data:`REQUEST_TIMEOUT`) to
    send its whole request, and as long to take a reply. The socket is bound by its name inside the directory
    checked through its descriptor (:class:`_Files`), which the server makes its working directory (so
    /proc/net/unix and ``ss -x`` show that name, not the whole path)."""
    global _SERVER_BLAS_THREADS, _PRCTL
    import traceback

    # warnings as one marked line each: a log of warnings only is no server failure
    warnings.showwarning = _log_warning
    _preload(preload)
    _PRCTL = _find_prctl()
    # once here rather than in every worker: threadpoolctl's scan of the loaded libraries costs tens of ms
    _limit_blas(1)
    _SERVER_BLAS_THREADS = 1
    # Move everything imported so far out of the garbage collector's reach: a forked job that runs a collection
    # would otherwise write to (and so copy) every page of the server's objects.
    gc.freeze()
    fp = fingerprint()
    if request_timeout is None:
        request_timeout = _seconds(REQUEST_TIMEOUT_VAR, REQUEST_TIMEOUT)
    files = _Files(path)
    os.fchdir(files.dir_fd)  # bind in the checked directory, not wherever its path may lead by now
    try:
        if stat.S_ISSOCK(files.stat().st_mode):
            files.unlink()  # a killed server's
    except FileNotFoundError:
        pass
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    srv.bind(files.name)
    socket_ino = files.stat().st_ino
    srv.listen(64)
    srv.setblocking(False)
    jobs, clients, owners = {}, [], set()
    state = {"accepting": True, "last": time.monotonic()}

    def close(client):
        client.sock.close()
        clients.remove(client)

    def flush(client):
        try:
            done = client.write()
        except (BlockingIOError, InterruptedError):
            return
        except OSError:  # the client is gone
            done = True
        if done:
            close(client)

    def answer(client, reply):
        client.answer(reply, time.monotonic() + request_timeout)
        flush(client)

    def inherited():
        fds = [srv.fileno(), files.dir_fd] + [c.sock.fileno() for c in clients]
        return fds + [fd for job in jobs.values() for fd in (job.conn.fileno(), job.result_r)]

    def on_request(client):
        try:
            frame = client.read()
            if frame is None:
                return
            request = _check_request(frame.message())
        except (BlockingIOError, InterruptedError):
            return
        except ProtocolError as exc:
            return answer(client, _reply("error", f"refused a request: {exc}"))
        except (EOFError, OSError):
            return close(client)
        if request.get("shutdown"):
            state["accepting"] = False
            return answer(client, _reply("bye"))
        if request.get("owner"):
            owners.add(request["owner"])
        if request["fingerprint"] != fp:  # the client hashed the sources just now
            state["accepting"] = False
            return answer(client, _reply("stale"))
        try:
            check_target(request["target"])
            _check_job(request["job"])
            _check_cwd(request["cwd"])
        except (JobRefused, ProtocolError) as exc:
            return answer(client, _reply("error", f"refused a request: {exc}"))
        clients.remove(client)
        try:
            job = _start_job(client.sock, request, inherited())
        except OSError:  # e.g. no memory to fork: the client runs its job itself
            traceback.print_exc()
            client.sock.close()
            return
        if job is not None:
            jobs[job.pid] = job

    def on_event(what):
        """Handle what ``poll`` found ready: the listening socket (None), a client, a job's result pipe, or a job's
        connection (its pid)."""
        if what is None:
            on_connect()
        elif isinstance(what, _Client):
            if what in clients and what.out is None:
                on_request(what)
            elif what in clients:
                flush(what)
        elif isinstance(what, _Job):
            if what.pid in jobs and (result := what.relay()) is not None:
                del jobs[what.pid]
                client = _Client(what.conn, 0)
                clients.append(client)
                answer(client, result)
        elif what in jobs:  # the client should not send more: readable means it closed
            jobs.pop(what).kill()

    def on_connect():
        try:
            conn, _ = srv.accept()
        except (BlockingIOError, InterruptedError):
            return
        except OSError:  # out of descriptors: let running jobs end first
            time.sleep(0.05)
            return
        state["last"] = time.monotonic()
        try:
            _, uid = _peer(conn)
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
            return
        conn.setblocking(False)
        client = _Client(conn, time.monotonic() + request_timeout)
        clients.append(client)
        on_request(client)  # its request has often arrived already

    try:
        while state["accepting"] or jobs or clients:
            now = time.monotonic()
            for client in [c for c in clients if c.deadline <= now]:
                if client.out is None:  # still reading: say why, if the socket takes it at once
                    client.answer(
                        _reply(
                            "error",
                            f"refused a request: not complete within {request_timeout:g} s",
                        ),
                        now,
                    )
                    try:
                        client.write()
                    except OSError:
                        pass
                close(client)
            if not state["accepting"]:
                # requests still coming in: closed, their clients run their jobs themselves
                for client in [c for c in clients if c.out is None]:
                    close(client)
            watch = {}
            if state["accepting"] and len(clients) < _MAX_CLIENTS:
                watch[srv.fileno()] = (select.POLLIN, None)
            for client in clients:
                watch[client.sock.fileno()] = (
                    select.POLLIN if client.out is None else select.POLLOUT,
                    client,
                )
            for job in jobs.values():
                watch[job.result_r] = (select.POLLIN, job)
                watch[job.conn.fileno()] = (select.POLLIN, job.pid)
            poll = select.poll()
            for fd, (events, _) in watch.items():
                poll.register(fd, events)
            wait = min([1.0] + [c.deadline - now for c in clients])
            for fd, _ in poll.poll(max(0.0, wait) * 1000):
                try:
                    on_event(watch[fd][1])
                except (
                    Exception
                ):  # a failure of the server itself: into its log, which is then kept
                    traceback.print_exc()
            if jobs:
                state["last"] = time.monotonic()
            if state["accepting"] and not jobs and not clients:
                if time.monotonic() - state["last"] > idle:
                    state["accepting"] = False
                elif owners and not any(_alive(pid) for pid in owners):
                    # the Snakemake run ended without the shutdown hook (killed)
                    state["accepting"] = False
    finally:
        srv.close()
        for job in jobs.values():  # only after an error of the server itself: stop its workers
            job.kill()
        for client in clients:
            client.sock.close()
        with files:
            lock = files.lock()
            try:
                files.remove(lock, socket_ino)
            finally:
                os.close(lock)


#: Environment variable that switches the job server off ("0") for shell jobs; the Snakefile sets it from the
#: config key job_server (an environment variable, not a rule param: where a job runs does not change its result,
#: so switching it must not rerun finished jobs).
USE_SERVER_VAR = "BSRBENCH_JOB_SERVER"


def configure_shell_jobs(use_server=True):
    """Prepare this process's environment, which Snakemake's shell jobs inherit, for ``python -m bsrbench.jobserver
    job``: this interpreter's directory first on ``PATH`` (so that ``python`` is the interpreter running Snakemake;
    a conda deployment activates its own environment inside the job, which then comes first), and
    :data:`USE_SERVER_VAR` set from the config key ``job_server``; ``PYTHONSAFEPATH=1``, so that no job's Python
    (shell, ``script:`` or this server) puts the working directory or a script's folder on its path
    (:mod:`bsrbench.pythonpath`)."""
    os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")
    os.environ["PYTHONSAFEPATH"] = "1"
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
    ap.add_argument("target", help="the job function, one of: " + ", ".join(JOB_TARGETS))
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
