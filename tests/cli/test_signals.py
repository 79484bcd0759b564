"""Interrupts: SIGTERM / SIGINT during a long write remove the temporary ``.part`` file, print
exactly one line and exit with 143 / 130 (128 + signal number)."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


def _sigint_as_in_a_terminal():
    """Ctrl-C's default in the child, whatever started the tests: a background job of a shell runs with
    SIGINT ignored, its children inherit that, and inscal rightly leaves an ignored signal ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _launch(args, cwd):
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    code = "import sys; from inscal.cli import main; sys.argv = ['inscal'] + sys.argv[1:]; main()"
    return subprocess.Popen([sys.executable, "-c", code, *args], cwd=cwd, env=env, preexec_fn=_sigint_as_in_a_terminal,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for_part(folder: Path, proc, timeout=60.0):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if any(p.name.endswith(".part") for p in folder.iterdir()):
            return True
        if proc.poll() is not None:
            return False
        time.sleep(0.02)
    return False


def _start(args, cwd, fork_servers, sig):
    """The command in a fork of a shared server (its interpreter and imports made once: ``inscal.cli.main`` with
    its real handlers and exit); for SIGINT in an interpreter of its own, whose Ctrl-C is the terminal's
    (:func:`_sigint_as_in_a_terminal`: a server started by a background job would hand on SIGINT ignored)."""
    if sig == signal.SIGINT:
        return _launch(args, cwd)
    return fork_servers.get().start(args, cwd, cwd.parent / f"{cwd.name}-logs")


@pytest.mark.parametrize("sig, code, name", [(signal.SIGTERM, 143, "SIGTERM"), (signal.SIGINT, 130, "SIGINT")])
def test_signal_during_simulate_removes_part(tmp_path, sig, code, name, fork_servers):
    proc = _start(["simulate", "static-24h", "--duration-h", "24", "--out", "x.h5", "--json"], tmp_path, fork_servers,
                  sig)
    try:
        assert _wait_for_part(tmp_path, proc), proc.communicate()
        time.sleep(0.05)  # well inside the write (a 24-h record takes about a second now)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"inscal: interrupted ({name}); removed partial output "), err
    assert "x.h5 not written" in lines[0] and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_sigterm_during_compensate_removes_part(tmp_path, fork_servers):
    """A streaming writer other than simulate (compensate: read chunks -> write chunks)."""
    from test_cli_guards import make_record, params_file

    rec = make_record(tmp_path / "r.h5", n=2_000_000)
    params_file(tmp_path / "p.toml")
    before = sorted(x.name for x in tmp_path.iterdir())
    proc = _start(["compensate", "r.h5", "--params", "p.toml", "--out", "c.h5", "--json"], tmp_path, fork_servers,
                  signal.SIGTERM)
    try:
        if not _wait_for_part(tmp_path, proc):
            out, err = proc.communicate()
            pytest.skip(f"compensate finished before the signal could be sent ({proc.returncode})")
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    if proc.returncode == 0:  # it finished between the check and the signal: the output is whole
        assert (tmp_path / "c.h5").exists()
        return
    assert proc.returncode == 143, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("inscal: interrupted (SIGTERM)"), err
    assert sorted(x.name for x in tmp_path.iterdir()) == before
    assert rec.exists()


def test_an_interrupt_wrapped_by_an_import_still_exits_143(tmp_path):
    """A signal whose exception is raised in a class body while a module is imported (matplotlib's, in a
    plotting command) reaches the command line as a RuntimeError of __set_name__: it is still the interrupt,
    one line and 143, not a traceback and a death by the re-arm timer's SIGALRM."""
    code = (
        "import os, signal, sys\n"
        "import inscal.cli.app\n"
        "A = sys.modules['inscal.cli.app']  # the package's face re-exports the Typer object as app\n"
        "class Arm:\n"
        "    def __set_name__(self, owner, name):\n"
        "        os.kill(os.getpid(), signal.SIGTERM)\n"
        "        for _ in range(1000): pass\n"
        "def command(prog_name):\n"
        "    class Axes:\n"
        "        set_xscale = Arm()\n"
        "A.app = command\n"
        "A.main()\n"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=60,
                       check=False)
    assert r.returncode == 143, (r.returncode, r.stderr)
    assert r.stderr.strip() == "inscal: interrupted (SIGTERM)", r.stderr
