"""The ``bdft`` program's exit: its output complete, its code kept, its threads waited for."""

import json
import shlex
import subprocess
import sys
import textwrap

import pytest

import bdft


def _bdft(*args, **kw):
    return subprocess.run(
        [sys.executable, "-m", "bdft", *args], capture_output=True, text=True, timeout=300, **kw
    )


def test_output_is_complete_and_the_code_kept():
    done = _bdft("validate", "--samples", "300", "--seed", "4", "--json")
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)  # the whole object reached the pipe
    assert out["samples"] == 300 and out["seed"] == 4
    bad = _bdft("validate", "--samples", "0")
    assert bad.returncode == 2
    assert "--samples" in bad.stderr and bad.stdout == ""


@pytest.mark.parametrize("thread", [False, True])
def test_exit_handlers_run_and_running_threads_are_waited_for(tmp_path, thread):
    flag, handler = tmp_path / "thread.txt", tmp_path / "atexit.txt"
    script = textwrap.dedent(
        f"""
        import atexit, sys, threading, time
        import bdft

        atexit.register(lambda: open({str(handler)!r}, "w").write("ran"))

        def late():
            time.sleep(1.0)
            open({str(flag)!r}, "w").write("done")

        sys.argv = ["bdft", "validate", "--samples", "50", "--json"]
        if {thread}:
            threading.Thread(target=late).start()  # not a daemon: the exit waits for it
        sys.exit(bdft.console())
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["samples"] == 50
    assert handler.read_text() == "ran"
    assert flag.exists() == thread
    if thread:
        assert flag.read_text() == "done"


def test_without_standard_output_the_code_is_kept():
    # fd 1 closed: sys.stdout is None (print writes nothing); nothing to flush there, the
    # exit code stays main's
    done = subprocess.run(
        f"{shlex.quote(sys.executable)} -m bdft validate --samples 50 >&-",
        shell=True,
        capture_output=False,
        stderr=subprocess.PIPE,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr


def test_program_returns_its_code_in_process(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["bdft", "validate", "--samples", "0"])
    assert bdft.program() == 2  # this process goes on: only console() ends it
    assert "--samples" in capsys.readouterr().err
