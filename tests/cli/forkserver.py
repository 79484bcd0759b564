"""A fork server for tests that run many short commands and check what each command does (exit code, its
lines, the files it leaves, its peak memory), not the interpreter's start: one child process imports the
command line and every module of the package once, then forks a grandchild per command, which runs
``inscal.cli.main`` with its own arguments, folder, stdout and stderr files (the real signal handlers, the
real exit), and reports ``(exit code, peak RSS in bytes, seconds from fork to exit)``.  A start costs about
1 s of CPU; a fork a few milliseconds.

POSIX only (``os.fork``); the server runs with one BLAS thread, as the suite does, so that forking is safe."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

SERVER = r"""
import importlib, json, os, pkgutil, sys, time
import inscal
from inscal.cli import main
for info in pkgutil.walk_packages(inscal.__path__, "inscal."):
    if not info.name.endswith("__main__"):
        importlib.import_module(info.name)
print("ready", flush=True)
for line in sys.stdin:
    req = json.loads(line)
    t0 = time.monotonic()
    pid = os.fork()
    if pid == 0:  # the command: its folder, its files on fds 0-2, its arguments, its exit code
        code = 1
        try:
            os.chdir(req["cwd"])
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
    print(json.dumps({"rc": rc, "rss": ru.ru_maxrss * 1024, "seconds": time.monotonic() - t0}), flush=True)
"""


class ForkServer:
    """``with ForkServer(env) as fs: fs.run(args, cwd, logs)`` -> ``{"rc", "rss", "seconds"}``; the command's
    stdout and stderr are in ``logs/stdout`` and ``logs/stderr``."""

    def __init__(self, env: dict | None = None):
        env = dict(os.environ if env is None else env)
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            env[var] = "1"
        self.proc = subprocess.Popen([sys.executable, "-c", SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True, env=env)
        ready = self.proc.stdout.readline()
        if ready.strip() != "ready":
            self.close()
            raise RuntimeError(f"the fork server did not start: {ready!r}")

    def run(self, args, cwd: Path, logs: Path, timeout: float = 120.0) -> dict:
        logs.mkdir(parents=True, exist_ok=True)
        req = {"args": [str(a) for a in args], "cwd": str(cwd), "stdout": str(logs / "stdout"),
               "stderr": str(logs / "stderr"), "timeout": timeout}
        self.proc.stdin.write(json.dumps(req) + "\n")
        self.proc.stdin.flush()
        return json.loads(self.proc.stdout.readline())

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
