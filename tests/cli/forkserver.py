"""A fork server for tests that run many short commands and check what each command does (exit code, its
lines, the files it leaves, its peak memory), not the interpreter's start: one child process imports the
command line and every module of the package once, then forks a grandchild per command, which runs
``inscal.cli.main`` with its own arguments, folder, stdout and stderr files (the real signal handlers, the
real exit), and reports ``(exit code, peak RSS in bytes, seconds from fork to exit, CPU seconds)``.  A start
costs about 2 s of CPU; a fork a few milliseconds.

POSIX only (``os.fork``); the server runs with one BLAS thread, as the suite does, so that forking is safe."""

from __future__ import annotations

import json
import os
import re
import select
import shlex
import signal
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

SERVER = r"""
import importlib, json, os, pkgutil, sys, time
import inscal
from inscal.cli import main
for info in pkgutil.walk_packages(inscal.__path__, "inscal."):
    if not info.name.endswith("__main__"):
        importlib.import_module(info.name)
if len(sys.argv) > 1:  # a warm-up: the kernels a command will run, compiled (or loaded from numba's cache) once
    exec(sys.argv[1])
print("ready", flush=True)
for line in sys.stdin:
    req = json.loads(line)
    t0 = time.monotonic()
    pid = os.fork()
    if pid == 0:  # the command: its folder, its files on fds 0-2, its arguments, its exit code
        code = 1
        try:
            os.chdir(req["cwd"])
            if req.get("environ") is not None:  # the command's whole environment, not the server's plus env
                os.environ.clear()
                os.environ.update(req["environ"])
            os.environ.update(req["env"])
            fds = [os.open(os.devnull, os.O_RDONLY)] + [os.open(req[k], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
                                                        for k in ("stdout", "stderr")]
            for target, fd in enumerate(fds):
                os.dup2(fd, target)
            sys.argv = ["inscal", *req["args"]]
            try:
                main()
                code = 0
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:
            import traceback
            traceback.print_exc()
        finally:
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.flush()
                except Exception:
                    pass
            os._exit(code)
    if req.get("announce"):
        print(json.dumps({"pid": pid}), flush=True)
    deadline = t0 + req["timeout"]
    while True:
        done, status, ru = os.wait4(pid, os.WNOHANG)
        if done:
            rc = os.waitstatus_to_exitcode(status)
            break
        if time.monotonic() > deadline:
            os.kill(pid, 9)
            _, status, ru = os.wait4(pid, 0)
            rc = None
            break
        time.sleep(0.002)
    print(json.dumps({"rc": rc, "rss": ru.ru_maxrss * 1024, "seconds": time.monotonic() - t0,
                      "cpu": ru.ru_utime + ru.ru_stime}), flush=True)
"""


#: a fault at a named step of the publication (env INSCAL_TEST_FAULT=STEP:SIGNAL): the step's function sends
#: the signal to its own process (run once in the fork server, so every forked command has the hooks)
FAULT_HOOKS = r"""
import os
import inscal.io.files as F, inscal.lab as L, inscal.lab.database as D, inscal.lab.journal as J
def _hook(step, fn):
    def at_step(*a, **k):
        name, _, sig = os.environ.get("INSCAL_TEST_FAULT", "").partition(":")
        if name == step:
            os.kill(os.getpid(), int(sig))
        return fn(*a, **k)
    return at_step
J.add = _hook("journal", J.add)        # the result staged, its files' journal being written: before the commit
F.publish = _hook("rename", F.publish)  # committed, before the first rename
J.publish = _hook("rename", J.publish)  # a recovery, before its rename
D.published = L.published = _hook("clear", D.published)  # every file in place, the journal not yet cleared
"""


class ForkServer:
    """``with ForkServer(env) as fs: fs.run(args, cwd, logs)`` -> ``{"rc", "rss", "seconds", "cpu"}``; the
    command's stdout and stderr are in ``logs/stdout`` and ``logs/stderr``.  ``fs.start(...)`` returns the running
    command (:class:`Forked`: its pid, to signal it) instead; one command at a time per server.  ``warm``:
    Python code the server runs once before its first fork (e.g. a calibration, so that every command finds
    the numba kernels it runs loaded already)."""

    def __init__(self, env: dict | None = None, warm: str | None = None):
        env = dict(os.environ if env is None else env)
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            env[var] = "1"
        # unbuffered bytes: a reply is read a byte at a time, never ahead, so select() on the pipe says
        # whether the running command's reply is there
        self.proc = subprocess.Popen([sys.executable, "-c", SERVER, *([warm] if warm else [])], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     bufsize=0, env=env)
        self.pending = 0  # commands sent whose end the server has not replied yet
        self.last_pid: int | None = None  # the last command started (``start``)
        ready = self.proc.stdout.readline()
        if ready.strip() != b"ready":
            self.close()
            raise RuntimeError(f"the fork server did not start: {ready!r}")

    def _send(self, args, cwd: Path, logs: Path, timeout: float, env: dict | None, announce: bool,
              environ: dict | None = None) -> None:
        logs.mkdir(parents=True, exist_ok=True)
        req = {"args": [str(a) for a in args], "cwd": str(cwd), "stdout": str(logs / "stdout"),
               "stderr": str(logs / "stderr"), "timeout": timeout, "env": dict(env or {}), "announce": announce,
               "environ": None if environ is None else dict(environ)}
        data = memoryview((json.dumps(req) + "\n").encode())
        while data:
            data = data[self.proc.stdin.write(data):]
        self.pending += 1

    def reply(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("the fork server ended")
        out = json.loads(line)
        if "rc" in out:
            self.pending -= 1
        return out

    def idle(self) -> bool:
        """Whether the server is running and no command of it is still running (replies already there are
        read: a test that ended without reading its command's)."""
        while self.pending and self.proc.poll() is None and select.select([self.proc.stdout], [], [], 0)[0]:
            self.reply()
        return self.proc.poll() is None and self.pending == 0

    def run(self, args, cwd: Path, logs: Path, timeout: float = 120.0, env: dict | None = None,
            environ: dict | None = None) -> dict:
        """``inscal ARGS`` in ``cwd`` (``env``: variables set for this command only; ``environ``: the command's
        whole environment instead of the server's)."""
        self._send(args, cwd, logs, timeout, env, announce=False, environ=environ)
        return self.reply()

    def start(self, args, cwd: Path, logs: Path, timeout: float = 120.0, env: dict | None = None) -> Forked:
        """``inscal ARGS`` in ``cwd``, running: ``poll()``, ``send_signal()``, ``wait()`` as for a Popen."""
        self._send(args, cwd, logs, timeout, env, announce=True)
        self.last_pid = self.reply()["pid"]
        return Forked(self, self.last_pid, logs)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.stdin.close()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class ServerPool:
    """Fork servers shared by the tests of one process (a session fixture of ``tests/cli/conftest.py``): a
    server costs ~2 s of CPU to start (the interpreter and every module of the package), a fork a few
    milliseconds, and a fork is the same whichever test started the server.  ``pool.get(k)``: the ``k``-th
    server (``k`` = 0, 1: two commands running at a time), started with ``env`` on first use and again if the
    one before ended or still owes a reply (a test that failed with its command running).  A test's own
    variables (``COLUMNS``, ``PATH``...) go with each command (``run(..., env=...)``): they are set in the
    fork, so they must not be in ``env`` (a fork can add a variable, not remove one)."""

    def __init__(self, env: dict | None = None):
        self.env = dict(os.environ if env is None else env)
        self.servers: dict[int, ForkServer] = {}

    def get(self, k: int = 0) -> ForkServer:
        server = self.servers.get(k)
        if server is None or not server.idle():
            if server is not None:  # a command still running (its test failed): it and its server end here
                if server.pending and server.last_pid is not None and server.proc.poll() is None:
                    try:
                        os.kill(server.last_pid, signal.SIGKILL)
                    except ProcessLookupError:
                        pass
                server.proc.kill()
                server.close()
            server = self.servers[k] = ForkServer(self.env)
        return server

    def close(self) -> None:
        for server in self.servers.values():
            server.close()
        self.servers.clear()


class Forked:
    """A command running in a fork of a :class:`ForkServer` (a grandchild of the test: the server reaps it and
    replies with its exit code when it ends)."""

    def __init__(self, server: ForkServer, pid: int, logs: Path):
        self.server, self.pid, self.logs = server, pid, logs
        self.result: dict | None = None

    @property
    def returncode(self) -> int | None:
        return None if self.result is None else self.result["rc"]

    def poll(self) -> int | None:
        if self.result is None and select.select([self.server.proc.stdout], [], [], 0)[0]:
            self.result = self.server.reply()
        return self.returncode

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, sig)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def wait(self, timeout: float | None = None) -> int:
        """The exit code (None: the server killed it at its own time limit); ``timeout``: as for a Popen."""
        if self.result is None:
            if timeout is not None and not select.select([self.server.proc.stdout], [], [], timeout)[0]:
                raise subprocess.TimeoutExpired(str(self.pid), timeout)
            self.result = self.server.reply()
        return self.returncode

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        """``(stdout, stderr)`` once it has ended."""
        self.wait(timeout)
        return (self.logs / "stdout").read_text(), (self.logs / "stderr").read_text()

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


#: what bash would read as more than plain words outside quotes: expansions, globs, redirections, lists
SHELL_SPECIAL = re.compile(r"[$`|;&<>(){}\[\]*?~\\]")


def plain_words(line: str) -> list[str] | None:
    """The words of a command line exactly as bash splits them, when it is plain words, quoted strings and a
    trailing ``# comment`` (nothing bash would expand, redirect or run in a list); else None."""
    rest, i, outside = line, 0, []
    while i < len(rest):
        c = rest[i]
        if c in "'\"":
            j = rest.find(c, i + 1)
            if j < 0 or (c == '"' and re.search(r"[$`\\]", rest[i + 1:j])):
                return None
            outside.append(" ")
            i = j + 1
            continue
        if c == "#" and (i == 0 or rest[i - 1].isspace()):
            break
        outside.append(c)
        i += 1
    if SHELL_SPECIAL.search("".join(outside)) or "#" in "".join(outside):
        return None
    return shlex.split(line, comments=True)


class Shell:
    """Lines of a README block, run in ``folder`` as bash runs them one after another, with the variables
    ``env``: ``export NAME=VALUE`` sets a variable for the lines after it, a plain ``inscal ...`` line runs in a
    fork of ``server`` (with ``script``, the first such line through the installed ``inscal`` script, so that
    the entry point is run too: one block of the suite is enough), any other line in bash.  ``run(line)``
    returns ``(returncode, stdout, stderr)`` as a namespace."""

    def __init__(self, server: ForkServer, folder: Path, env: dict, logs: Path, script: bool = True):
        self.server, self.folder, self.env, self.logs = server, folder, dict(env), logs
        self.extra: dict = {}
        self.count = 0
        self.script_ran = not script

    def run(self, line: str, timeout: float = 600.0) -> SimpleNamespace:
        words = plain_words(line)
        if words is not None and len(words) == 2 and words[0] == "export" and "=" in words[1]:
            name, value = words[1].split("=", 1)
            self.extra[name] = value
            return SimpleNamespace(returncode=0, stdout="", stderr="")
        if words and words[0] == "inscal" and self.script_ran:
            self.count += 1
            logs = self.logs / f"{self.count:03d}"
            r = self.server.run(words[1:], self.folder, logs, timeout=timeout, env=self.extra, environ=self.env)
            return SimpleNamespace(returncode=r["rc"], stdout=(logs / "stdout").read_text(),
                                   stderr=(logs / "stderr").read_text())
        self.script_ran = self.script_ran or bool(words and words[0] == "inscal")
        r = subprocess.run(["bash", "-c", line], cwd=self.folder, env={**self.env, **self.extra}, capture_output=True,
                           text=True, timeout=timeout, check=False)
        return SimpleNamespace(returncode=r.returncode, stdout=r.stdout, stderr=r.stderr)
