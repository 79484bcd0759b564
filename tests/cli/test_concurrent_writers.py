"""Two writers on one output: every writing subcommand refuses an output whose lock (``.NAME.lock``
beside it, :func:`inscal.io.files.claim_output`) another process holds, up front and in one line,
writing nothing; two real processes racing for one output leave exactly one whole output; a file
that appears at an output while a command runs is not replaced without ``--force``; and the
outputs of one command are published together or not at all."""

import fcntl
import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager

import h5py
import numpy as np
import pytest
from test_cli_guards import make_record, one_line_error, params_file, run
from test_signals_under_load import started

from inscal import io
from inscal.core import cancel as core_cancel
from inscal.cli.interrupts import Interrupted, catch_interrupts, release_interrupts
from inscal.io.files import OutputBusyError, atomic_path, claim_output, lock_path, output_unit, release_output
from inscal.io.files import part_prefix as files_prefix

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX locks and signals")


@contextmanager
def held_by_another(path):
    """Hold the lock of ``path`` on a descriptor of our own (flock locks are per open file, so this
    process's own claims conflict with it exactly as another process's would)."""
    lock = lock_path(path)
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.write(fd, b"424242\n")
        yield lock
    finally:
        os.close(fd)
        lock.unlink(missing_ok=True)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("writers-in")
    rec = make_record(d / "r.h5", n=3000)
    params_file(d / "p.toml")
    code, _, err = run("export", rec, "--format", "psins", "--out", d / "r.txt")
    assert code == 0, err
    return {"rec": rec, "params": d / "p.toml", "txt": d / "r.txt"}


#: every writing subcommand with the output it writes ({out}: the output's path)
WRITERS = {
    "simulate": ["simulate", "psins19", "--rate-hz", "10", "--out", "{out}.h5"],
    "compensate": ["compensate", "{rec}", "--params", "{params}", "--out", "{out}.h5"],
    "import": ["import", "{txt}", "--format", "psins", "--rate-hz", "100", "--out", "{out}.h5"],
    "export": ["export", "{rec}", "--format", "csv", "--out", "{out}.csv"],
    "calibrate": ["calibrate", "{rec}", "--method", "six-position", "--out", "{out}.toml"],
    "navigate": ["navigate", "{rec}", "--init", "align", "--align-coarse-s", "5", "--align-fine-s", "5",
                 "--out", "{out}.h5"],
    "navigate --plot": ["navigate", "{rec}", "--init", "align", "--align-coarse-s", "5", "--align-fine-s", "5",
                        "--plot", "{out}.png"],
    "design": ["design", "--minutes", "10", "--scheduler", "none", "--out", "{out}.toml"],
    "report": ["report", "{rec}", "--out", "{out}.html"],
    "allan": ["allan", "{rec}", "--plot", "{out}.png"],
}


@pytest.mark.parametrize("name", list(WRITERS))
def test_an_output_being_written_by_another_process_is_refused(inputs, tmp_path, name):
    argv = [a.format(out=tmp_path / "x", **inputs) for a in WRITERS[name]]
    out = next(a for a in argv if a.startswith(str(tmp_path / "x")))
    with held_by_another(out) as lock:
        before = sorted(p.name for p in tmp_path.iterdir())
        t0 = time.perf_counter()
        code, _, err = run(*argv)
        line = one_line_error(code, err)
        assert "is being written by another process (pid 424242" in line, line
        assert sorted(p.name for p in tmp_path.iterdir()) == before == [lock.name]
        assert time.perf_counter() - t0 < 5.0  # refused before any work
    for src in inputs.values():
        assert src.exists()


def test_montecarlo_refuses_a_study_folder_in_use(tmp_path):
    """The Monte Carlo study folder has its own lock (several runs append to one results file)."""
    out = tmp_path / "mc"
    out.mkdir()
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        code, _, err = run("montecarlo", "n25-fig5", "--runs", "2", "--out", out, "--no-dask")
    finally:
        os.close(fd)
    line = one_line_error(code, err)
    assert "another" in line.lower() or "in use" in line.lower(), line


def _launch(args, cwd):
    code = "import sys; from inscal.cli import main; sys.argv = ['inscal'] + sys.argv[1:]; main()"
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))


@pytest.fixture()
def servers(fork_servers):
    """Two fork servers: the two racing commands are forks of two processes that imported the package, so
    they start within milliseconds of each other."""
    return [fork_servers.get(0), fork_servers.get(1)]


@pytest.mark.parametrize("name", ["simulate", "compensate", "export"])
def test_two_processes_racing_for_one_output_leave_one_whole_output(inputs, servers, tmp_path, name):
    """Started together, with and without --force: one wins (exit 0), the other says why in one line
    (exit 2: the output is being written, or it exists) and does not replace it."""
    argv = [a.format(out=tmp_path / "x", **inputs) for a in WRITERS[name]]
    out = tmp_path / next(a for a in argv if a.startswith(str(tmp_path / "x"))).rsplit("/", 1)[1]
    for k, extra in enumerate(([], ["--force"])):
        out.unlink(missing_ok=True)
        procs = [server.start(argv + extra, tmp_path, tmp_path.parent / f"{tmp_path.name}-logs-{k}{i}")
                 for i, server in enumerate(servers)]
        res = [(p.wait(120), *p.communicate()) for p in procs]
        codes = sorted(r[0] for r in res)
        if extra and codes == [0, 0]:  # --force: the second began after the first had finished
            continue
        assert codes == [0, 2], res
        err = next(r[2] for r in res if r[0] == 2)
        assert err.count("\n") == 1 and ("being written by another process" in err or "exists" in err), err
        assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]  # no lock and no .part left
        if name != "export":
            io.read_record(out) if name != "compensate" else h5py.File(out, "r").close()


def test_a_file_that_appears_while_a_command_runs_is_not_replaced(servers, tmp_path):
    """Without --force, an output created by someone else after the command checked it survives."""
    proc = servers[0].start(["simulate", "static-24h", "--duration-h", "6", "--out", "x.h5"], tmp_path,
                            tmp_path.parent / f"{tmp_path.name}-logs")
    try:
        t0 = time.monotonic()
        while not any(p.name.endswith(".part") for p in tmp_path.iterdir()) and time.monotonic() - t0 < 60:
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.02)
        (tmp_path / "x.h5").write_text("the user's own file")
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 2, err
    assert err.count("\n") == 1 and "x.h5 appeared while this command ran; not replaced" in err, err
    assert (tmp_path / "x.h5").read_text() == "the user's own file"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.h5"]


# ----------------------------------------------------------------------------- the library's pieces
def test_claims_conflict_and_release(tmp_path):
    out = tmp_path / "a.h5"
    assert claim_output(out) is True and claim_output(out) is False  # held by this process: no conflict
    assert lock_path(out).exists()
    fd = os.open(lock_path(out), os.O_RDWR)
    with pytest.raises(BlockingIOError):
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    os.close(fd)
    release_output(out)
    assert not lock_path(out).exists()
    with held_by_another(out), pytest.raises(OutputBusyError, match="pid 424242"):
        with atomic_path(out) as tmp:
            tmp.write_text("never")
    assert list(tmp_path.iterdir()) == []


def test_a_lock_left_by_a_killed_writer_is_taken_over(tmp_path):
    """SIGKILL leaves the lock file, not the lock: the next writer takes it and removes it."""
    out = tmp_path / "a.txt"
    code = ("import sys, time; from inscal.io.files import claim_output; claim_output(sys.argv[1]); "
            "print('held', flush=True); time.sleep(60)")
    p = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "held"
    with pytest.raises(OutputBusyError):
        claim_output(out)
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert lock_path(out).exists()
    with atomic_path(out) as tmp:
        tmp.write_text("mine")
    assert out.read_text() == "mine" and sorted(x.name for x in tmp_path.iterdir()) == ["a.txt"]


@pytest.mark.parametrize("missing", ["", "renameat2", "renameat2+link"])
def test_publication_never_replaces_a_file_that_is_there(tmp_path, monkeypatch, missing):
    """The rename refuses an existing target in one atomic step: renameat2(RENAME_NOREPLACE), else a hard link,
    else an exclusive placeholder (a file system without hard links); --force replaces atomically."""
    from inscal.io import files

    if "renameat2" in missing:
        monkeypatch.setattr(files, "_renameat2", lambda src, dst: False)
    if "link" in missing:
        def no_link(src, dst):
            raise PermissionError(1, "Operation not permitted")

        monkeypatch.setattr(files.os, "link", no_link)
    src, dst = tmp_path / ".a.part", tmp_path / "a.toml"
    src.write_text("new")
    dst.write_text("theirs")
    with pytest.raises(FileExistsError, match="appeared while this command ran"):
        files.publish(src, dst, overwrite=False)
    assert dst.read_text() == "theirs" and src.read_text() == "new"
    files.publish(src, tmp_path / "b.toml", overwrite=False)
    assert (tmp_path / "b.toml").read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["a.toml",
                                                                                                         "b.toml"]
    (tmp_path / ".c.part").write_text("forced")
    files.publish(tmp_path / ".c.part", dst, overwrite=True)
    assert dst.read_text() == "forced"


def test_the_temporaries_a_killed_writer_left_are_removed_by_the_next(tmp_path):
    out = tmp_path / "p.toml"
    stale = tmp_path / (files_prefix(out) + "abcd1234.part")
    stale.write_text("half")
    other = tmp_path / ".p.toml.x.part"  # not a name of ours (the random part has 8 characters)
    other.write_text("keep")
    with atomic_path(out) as tmp:
        tmp.write_text("whole")
    assert out.read_text() == "whole" and not stale.exists() and other.exists()


def test_a_legal_name_of_255_bytes_in_two_byte_characters_has_its_lock_and_temporary(tmp_path):
    """A name of 125 two-byte characters and .toml (255 bytes, the most ext4 allows): its lock and temporary
    names are cut on a character boundary, within 255 bytes, and apart from those of a name one character off."""
    from inscal.io.files import part_prefix

    out, near = tmp_path / ("é" * 125 + ".toml"), tmp_path / ("é" * 124 + "e.toml")
    assert len(os.fsencode(out.name)) == 255
    for p in (out, near):
        for side in (lock_path(p).name, part_prefix(p) + "abcd1234.part"):
            assert len(os.fsencode(side)) <= 255 and "\ufffd" not in side
    assert lock_path(out) != lock_path(near) and part_prefix(out) != part_prefix(near)
    with atomic_path(out) as tmp:
        tmp.write_text("whole")
    assert out.read_text() == "whole" and sorted(p.name for p in tmp_path.iterdir()) == [out.name]


def test_output_unit_publishes_all_or_nothing(tmp_path):
    a, b, plots = tmp_path / "a.toml", tmp_path / "b.txt", tmp_path / "plots"
    with pytest.raises(RuntimeError), output_unit():
        with atomic_path(a) as tmp:
            tmp.write_text("a")
        assert not a.exists()  # held back until the unit ends
        io.files.make_output_dir(plots)
        with atomic_path(plots / "1.png") as tmp:
            tmp.write_text("1")
        raise RuntimeError("the second output failed")
    assert list(tmp_path.iterdir()) == []  # nothing published, the folder made for the unit removed
    with output_unit():
        with output_unit():  # an inner unit hands its outputs to the outer one
            with atomic_path(a) as tmp:
                tmp.write_text("a")
        with atomic_path(b) as tmp:
            tmp.write_text("b")
        assert not a.exists() and not b.exists()
    assert a.read_text() == "a" and b.read_text() == "b"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.toml", "b.txt"]


def test_sigterm_during_calibrate_with_plots_leaves_all_or_nothing(tmp_path):
    """SIGTERM at random times during ``calibrate --method systematic51 --plots``: the parameter file
    and the plots are one unit: either none is there (exit 143, one line), or all are (the signal came
    after they were published; the line says so) or the run finished (exit 0)."""
    rec = tmp_path / "p19.h5"
    code, _, err = run("simulate", "psins19", "--rate-hz", "20", "--seed", "3", "--out", rec)
    assert code == 0, err
    rng = np.random.default_rng(7)
    outcomes = []
    for delay in rng.uniform(0.0, 5.0, 4):
        for p in list(tmp_path.iterdir()):
            if p != rec:
                p.unlink() if p.is_file() else __import__("shutil").rmtree(p)
        proc = _launch(["calibrate", rec.name, "--method", "systematic51", "--out", "p.toml", "--plots", "plots"],
                       tmp_path)
        started(proc)
        time.sleep(delay)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        names = sorted(p.name for p in tmp_path.iterdir())
        if proc.returncode == 0 or "after its outputs were complete" in err:
            assert names == ["p.toml", "p19.h5", "plots"] and any((tmp_path / "plots").iterdir()), (names, err)
            outcomes.append("whole")
        else:
            assert proc.returncode == 143, err
            lines = [ln for ln in err.splitlines() if ln.strip()]
            assert len(lines) == 1 and lines[0].startswith("inscal: interrupted (SIGTERM)"), err
            assert names == ["p19.h5"], (names, err)
            outcomes.append("none")
    assert "none" in outcomes


def test_a_failed_unit_removes_its_folder_even_with_a_write_still_open(tmp_path):
    """An interrupt Python swallows inside a plot's write (in a callback) leaves that write's temporary open;
    when the interrupt comes again and the unit fails, the folder it made goes, with the temporary."""
    from inscal.io.files import make_output_dir

    with pytest.raises(RuntimeError), output_unit():
        plots = make_output_dir(tmp_path / "plots")
        write = atomic_path(plots / "a.png")
        tmp = write.__enter__()  # its exit never runs
        tmp.write_bytes(b"half a png")
        raise RuntimeError("interrupted again")
    assert list(tmp_path.iterdir()) == []


def _signalling(real, when=lambda *args: True):
    """``real`` followed by a SIGTERM to this process when ``when(*args)``: the handler runs at the next
    bytecode unless the step holds the signal."""

    def call(*args, **kwargs):
        out = real(*args, **kwargs)
        if when(*args):
            os.kill(os.getpid(), signal.SIGTERM)
        return out

    return call


@pytest.mark.parametrize("where", ["temporary", "lock", "folder"])
def test_an_interrupt_as_a_file_or_folder_is_made_leaves_nothing(tmp_path, monkeypatch, where):
    """A SIGTERM that arrives as the temporary (``mkstemp``), the lock file (``os.open``) or an output folder
    (``mkdir``) is made, before the cleanup knows of it (a navigate run under load left its ``.part`` so):
    with the command line's handler, what was made goes with the interrupt, also where another thread of
    the process received the signal (as in an xdist worker)."""
    if where == "temporary":
        monkeypatch.setattr(io.files.tempfile, "mkstemp", _signalling(io.files.tempfile.mkstemp))
    elif where == "lock":
        monkeypatch.setattr(io.files.os, "open", _signalling(os.open, lambda p, *a: str(p).endswith(".lock")))
    else:
        monkeypatch.setattr(io.files.FsPath, "mkdir", _signalling(io.files.FsPath.mkdir))
    monkeypatch.setattr(core_cancel, "_CANCEL", [])  # the handler's cancellation, for this test only
    old = catch_interrupts()
    try:
        with pytest.raises(Interrupted), output_unit():
            folder = io.files.make_output_dir(tmp_path / "plots")
            with atomic_path(folder / "x.h5") as tmp:
                tmp.write_text("never")
    finally:
        release_interrupts(old)
        monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []
