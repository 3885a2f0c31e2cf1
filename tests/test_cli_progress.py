"""Progress lines of long stages (scene3D.cli.common.StderrProgress): elapsed time and
time left on a terminal or with --progress, nothing elsewhere and nothing with -q."""

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
    if shown:
        assert lines[-2].startswith("views: 2 of 2 done in ") and lines[-2].endswith(" s")
        assert lines[-1].startswith("pairs: 1 of 1 done in ") and lines[-1].endswith(" s")
    else:
        assert lines == []
