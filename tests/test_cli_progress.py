"""Progress lines of long stages (scene3D.cli.common.StderrProgress): elapsed time and
time left on a terminal or with --progress, nothing elsewhere and nothing with -q."""

import argparse
import os
import pty
import subprocess
import sys

import pytest

from scene3D.cli import common
from scene3D.cli.common import StderrProgress, duration_text


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch):
    c = _Clock()
    monkeypatch.setattr(common.time, "monotonic", c)
    return c


def _run(progress, clock):
    """Tasks finishing every 2 s: 0 of 4 at t=0, then 1..4 of 4 at t=2, 4, 6, 8."""
    progress("pairs", 0, 4)
    for done in range(1, 5):
        clock.now += 2.0
        progress("pairs", done, 4)


def test_terminal_lines_say_elapsed_and_time_left(clock, capsys):
    _run(StderrProgress(terminal=True, interval_s=1.0), clock)
    lines = capsys.readouterr().err.splitlines()
    # After 1 of 4 tasks in 2 s the other 3 take 6 s more; after 3 of 4, 2 s.
    assert lines == ["pairs: 0 of 4 done",
                     "pairs: 1 of 4 done, 2.0 s so far, about 6.0 s left",
                     "pairs: 2 of 4 done, 4.0 s so far, about 4.0 s left",
                     "pairs: 3 of 4 done, 6.0 s so far, about 2.0 s left",
                     "pairs: 4 of 4 done in 8.0 s"]


def test_not_a_terminal_and_quiet_give_no_line(clock, capsys):
    _run(StderrProgress(terminal=False), clock)
    assert capsys.readouterr().err == ""
    _run(StderrProgress(), clock)  # terminal=None: asks stderr, here pytest's capture
    assert capsys.readouterr().err == ""
    _run(StderrProgress(enabled=False, terminal=True), clock)
    assert capsys.readouterr().err == ""


def test_lines_are_rate_limited_and_a_second_stage_starts_its_own_clock(clock, capsys):
    progress = StderrProgress(terminal=True, interval_s=5.0)
    _run(progress, clock)  # lines at t=0 (0 of 4), then t=6 (3 of 4), and the last
    _run(progress, clock)
    lines = capsys.readouterr().err.splitlines()
    assert lines[:3] == ["pairs: 0 of 4 done",
                         "pairs: 3 of 4 done, 6.0 s so far, about 2.0 s left",
                         "pairs: 4 of 4 done in 8.0 s"]
    assert lines[-1] == "pairs: 4 of 4 done in 8.0 s"  # not 16 s: the clock restarted


def test_the_commands_engine_starts_the_clock_when_the_map_starts(clock, capsys):
    """The engines report finished tasks only; the first task's time counts too."""
    def task(seconds):
        clock.now += seconds
        return seconds

    args = argparse.Namespace(quiet=False, progress=True, verbose=0)
    with common.open_engine(args) as engine:
        assert list(engine.map(task, [(2.0,), (2.0,), (2.0,)], label="views")) == [2.0] * 3
        assert list(engine.map(task, [], label="pairs")) == []
    assert capsys.readouterr().err.splitlines() == [
        "views: 0 of 3 done",
        "views: 1 of 3 done, 2.0 s so far, about 4.0 s left",
        "views: 2 of 3 done, 4.0 s so far, about 2.0 s left",
        "views: 3 of 3 done in 6.0 s"]


@pytest.mark.parametrize("seconds, text", [(0.44, "0.4 s"), (12.4, "12 s"), (185.0, "3 min 05 s"),
                                           (3720.0, "1 h 02 min")])
def test_duration_text(seconds, text):
    assert duration_text(seconds) == text


# -- the command: a real terminal (a pseudo-terminal), a pipe, --progress and -q ----------

def _evaluate(fountain, flags: list[str], on_a_terminal: bool) -> tuple[int, str]:
    """``scene3d evaluate`` on one small pair, its stderr a pty or a pipe: (code, stderr)."""
    command = [sys.executable, "-c", "import sys; from scene3D.cli import console_main; "
               "sys.argv[0] = 'scene3d'; sys.exit(console_main())", "evaluate", str(fountain),
               "--pairs", "4-5", "--max-width", "400", *flags]
    if not on_a_terminal:
        proc = subprocess.run(command, capture_output=True, text=True, timeout=120)
        return proc.returncode, proc.stderr
    parent, child = pty.openpty()
    with subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=child) as proc:
        os.close(child)
        chunks = []
        while True:
            try:
                chunk = os.read(parent, 4096)
            except OSError:  # EIO: the child closed its end of the terminal
                break
            if not chunk:
                break
            chunks.append(chunk)
        code = proc.wait(timeout=120)
    os.close(parent)
    return code, b"".join(chunks).decode().replace("\r\n", "\n")


def _progress_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith(("views:", "pairs:"))]


@pytest.mark.parametrize("flags, on_a_terminal, shown", [
    ([], True, True), ([], False, False), (["--progress"], False, True),
    (["-q"], True, False), (["-q", "--progress"], False, False)])
def test_the_command_shows_progress_on_a_terminal_or_when_asked(fountain, flags,
                                                               on_a_terminal, shown):
    code, err = _evaluate(fountain, flags, on_a_terminal)
    assert code == 0, err
    lines = _progress_lines(err)
    if shown:  # each stage's clock starts at "0 of N"; its last line says the whole time
        assert lines[0] == "views: 0 of 2 done" and "pairs: 0 of 1 done" in lines
        views_done = [line for line in lines if line.startswith("views: 2 of 2 done in ")]
        assert len(views_done) == 1 and views_done[0].endswith(" s")
        assert lines[-1].startswith("pairs: 1 of 1 done in ") and lines[-1].endswith(" s")
    else:
        assert lines == []
