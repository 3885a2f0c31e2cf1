"""The ``scene3d`` command's set-up (scene3D.cli): what reaches the user's terminal."""

import os
import subprocess
import sys

from .conftest import REPO


def test_opencv_and_ffmpeg_log_lines_do_not_come_before_the_error(tmp_path):
    """A text file given as a video: FFmpeg printed 'moov atom not found' before the
    command's own line; now that line is all (a value the user sets is still used)."""
    fake = tmp_path / "board.mp4"
    fake.write_text("hello\n")  # FFmpeg takes it for an MP4 without its index
    env = {k: v for k, v in os.environ.items() if not k.startswith("OPENCV_")}
    args = [sys.executable, str(REPO / "calibrate.py"), "--video", str(fake),
            "--out", str(tmp_path / "camera.yaml")]
    proc = subprocess.run(args, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr == f"error: cannot open video '{fake}'\n"
    loud = subprocess.run(args, env={**env, "OPENCV_FFMPEG_LOGLEVEL": "32"},
                          capture_output=True, text=True, timeout=120)
    assert "moov atom not found" in loud.stdout + loud.stderr  # (stdout, at that level)


def test_a_command_run_in_process_leaves_the_callers_logging_alone(tmp_path, capsys):
    """From a notebook or a test: the command logs to the stderr of the moment while it
    runs (-v: INFO lines), and the root logger's handlers and level are the caller's again
    afterwards (basicConfig(force=True) replaced them, bound to the stderr of the time)."""
    import logging

    from scene3D.cli.evaluate import main

    root = logging.getLogger()
    mine = logging.StreamHandler()
    before = root.handlers[:]
    root.addHandler(mine)
    root.setLevel(logging.CRITICAL)
    try:
        assert main([str(tmp_path / "nope"), "-v"]) == 2
        assert capsys.readouterr().err.endswith(f"error: scene folder not found: "
                                                f"'{tmp_path / 'nope'}'\n")
        assert root.handlers == [*before, mine] and root.level == logging.CRITICAL
    finally:
        root.removeHandler(mine)
        root.setLevel(logging.WARNING)
