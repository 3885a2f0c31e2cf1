"""Calibration against published references and rendered boards with known intrinsics."""

import shutil
import subprocess
import sys

import cv2
import numpy as np
import pytest

from scene3D.calibration import (
    BoardSpec,
    Detection,
    calibrate,
    corner_coverage,
    coverage_warnings,
    detect_board,
    load_calibration,
)
from scene3D.cli.calibrate import main
from scene3D.synthetic import render_board

from .conftest import REPO
from .helpers import detect_folder

# OpenCV's modules/python/test/test_calibration.py, for opencv-left (9x6).
OPENCV_LEFT_K = np.array([[532.80992189, 0, 342.4952186], [0, 532.93346422, 233.8879292],
                          [0, 0, 1]])
TRUE_K = np.array([[610.0, 0, 331.0], [0, 598.0, 236.0], [0, 0, 1]])
TRUE_DIST = np.array([-0.22, 0.06, 0.0008, -0.0005, 0.0])
# Board poses that keep the whole 9x6 board in a 640x480 view.
POSES = [((0.4 * np.sin(a), 0.4 * np.cos(a), 0.1 * np.sin(2 * a)),
          (-4.5 + 1.5 * np.cos(a), -2.5 + 1.0 * np.sin(a), 14.0 + 1.5 * np.sin(3 * a)))
         for a in np.linspace(0, 2 * np.pi, 10, endpoint=False)]


@pytest.fixture(scope="module")
def board_views():
    return [render_board(TRUE_K, TRUE_DIST, np.array(r), np.array(t), supersample=2)
            for r, t in POSES]


def test_opencv_left_matches_the_published_calibration(chessboards):
    board = BoardSpec()
    dets = detect_folder(chessboards / "opencv-left", board)
    assert len(dets) == 13
    result = calibrate(dets, (640, 480), board)
    assert result.rms_px < 0.25
    np.testing.assert_allclose(result.K, OPENCV_LEFT_K, atol=2.0)
    assert len(result.per_view_errors_px) == 13
    assert result.std_intrinsics["fx"] < 2.0


def test_charuco_matches_its_published_calibration(chessboards):
    folder = chessboards / "opencv-charuco"
    fs = cv2.FileStorage(str(folder / "tutorial_camera_charuco.yml"), cv2.FILE_STORAGE_READ)
    published = fs.getNode("camera_matrix").mat()
    fs.release()
    board = BoardSpec("charuco", (5, 7), 0.04, 0.02, "DICT_6X6_250")
    dets = detect_folder(folder, board)
    assert len(dets) == 4
    result = calibrate(dets, (640, 480), board, reject_outliers=False)
    assert result.rms_px < 0.25
    # Within two of our standard deviations of the published values.
    for name, (i, j) in {"fx": (0, 0), "fy": (1, 1), "cx": (0, 2), "cy": (1, 2)}.items():
        assert abs(result.K[i, j] - published[i, j]) < 2 * result.std_intrinsics[name] + 1.0


def test_rendered_boards_give_the_true_intrinsics(board_views):
    board = BoardSpec()
    dets = [detect_board(img, board, f"v{i}") for i, img in enumerate(board_views)]
    assert all(d is not None for d in dets)
    result = calibrate(dets, (640, 480), board)
    assert result.rms_px < 0.2
    assert abs(result.K[0, 0] / TRUE_K[0, 0] - 1) < 0.005
    assert abs(result.K[1, 1] / TRUE_K[1, 1] - 1) < 0.005
    assert np.hypot(*(result.K[:2, 2] - TRUE_K[:2, 2])) < 2.0
    assert abs(result.dist[0] - TRUE_DIST[0]) < 0.03


def test_outlier_view_is_dropped_and_reported(board_views):
    board = BoardSpec()
    dets = [detect_board(img, board, f"v{i}") for i, img in enumerate(board_views)]
    rng = np.random.default_rng(0)
    bad = dets[3]
    dets[3] = Detection(bad.name, bad.image_points + rng.normal(0, 3.0, bad.image_points.shape),
                        bad.object_points, bad.method)
    result = calibrate(dets, (640, 480), board)
    assert list(result.rejected_views) == ["v3"]
    assert "v3" not in result.per_view_errors_px
    assert result.rms_px < 0.2


def test_too_few_views_fail(board_views):
    from scene3D.errors import CalibrationError

    board = BoardSpec()
    dets = [detect_board(img, board, f"v{i}") for i, img in enumerate(board_views[:2])]
    with pytest.raises(CalibrationError, match="at least 3"):
        calibrate(dets, (640, 480), board)


def test_corners_that_fit_no_camera_are_refused(board_views):
    from scene3D.errors import CalibrationError

    board = BoardSpec()
    dets = [detect_board(img, board, f"v{i}") for i, img in enumerate(board_views)]
    rng = np.random.default_rng(1)
    noisy = [Detection(d.name, d.image_points + rng.normal(0, 4.0, d.image_points.shape),
                       d.object_points, d.method) for d in dets]
    with pytest.raises(CalibrationError, match="do not fit one camera"):
        calibrate(noisy, (640, 480), board)
    assert calibrate(noisy, (640, 480), board, max_rms_px=None).rms_px > 2.0
    assert calibrate(dets, (640, 480), board).rms_px < 0.2


def test_cli_refuses_a_wrong_board_size(tmp_path, chessboards, capsys):
    # On the 9x6 board, a 5x5 search finds corner sets that are not a 5x5 grid.
    argv = ["--images", str(chessboards / "opencv-left"), "--board", "5x5",
            "--out", str(tmp_path / "c.yaml")]
    assert main(argv) == 1
    err = capsys.readouterr().err
    # One line of error, after the warning that names the photos without a 5x5 board.
    warning, error = err.strip().splitlines()
    assert warning.startswith("WARNING: the board was not found in 6 of the 13 photos")
    assert "do not fit one camera" in error and "check --board" in error
    assert list(tmp_path.iterdir()) == []
    assert main(argv + ["--max-rms", "50", "-q"]) == 0  # the user can insist


def test_coverage_grid_and_warnings():
    centre = [np.array([[320.0, 240.0], [330.0, 250.0]])]
    counts = corner_coverage(centre, (640, 480), grid=(8, 6))
    assert counts.shape == (6, 8) and counts.sum() == 2
    assert any("border" in w for w in coverage_warnings(counts))
    xs, ys = np.meshgrid(np.linspace(5, 635, 30), np.linspace(5, 475, 30))
    everywhere = [np.column_stack([xs.ravel(), ys.ravel()])]
    assert coverage_warnings(corner_coverage(everywhere, (640, 480))) == []


def test_board_spec_validation():
    with pytest.raises(ValueError, match="pattern"):
        BoardSpec("circles")
    with pytest.raises(ValueError, match="marker"):
        BoardSpec("charuco", (5, 7), 0.04, 0.05)
    with pytest.raises(ValueError, match="dictionary"):
        BoardSpec("charuco", (5, 7), 0.04, 0.02, "DICT_NOPE")


# -- the command ---------------------------------------------------------------------

def fs_value(path, key):
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        return fs.getNode(key).real()
    finally:
        fs.release()


def test_cli_on_opencv_left_writes_a_readable_calibration(tmp_path, chessboards, capsys):
    out = tmp_path / "left.yaml"
    code = main(["--images", str(chessboards / "opencv-left"), "--out", str(out),
                 "--square-size", "0.025"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "RMS reprojection error" in captured.out and f"Wrote '{out}'" in captured.out
    fs = cv2.FileStorage(str(out), cv2.FILE_STORAGE_READ)
    assert fs.getNode("image_width").real() == 640
    assert fs.getNode("rms_px").real() < 0.25
    assert fs.getNode("per_view_errors").mat().shape == (1, 13)
    assert "chessboard 9x6" in fs.getNode("board").string()
    fs.release()
    camera = load_calibration(out)
    np.testing.assert_allclose(camera.K, OPENCV_LEFT_K, atol=2.0)
    assert (tmp_path / "left_coverage.png").exists()
    assert (tmp_path / "left_view_errors.png").exists()
    assert (tmp_path / "left_uncertainty.png").read_bytes().startswith(b"\x89PNG")
    assert "projection uncertainty (1 sigma): median" in captured.out
    assert fs_value(out, "projection_uncertainty_median_px") < 1.0
    report = (tmp_path / "left_report.html").read_text()
    assert "Projection uncertainty" in report and "left14.jpg" in report
    # --no-report: no report, and an existing one is no reason to refuse.
    (tmp_path / "left_report.html").unlink()
    assert main(["--images", str(chessboards / "opencv-left"), "--out",
                 str(tmp_path / "other.yaml"), "--no-report", "-q"]) == 0
    assert not (tmp_path / "other_report.html").exists()
    assert (tmp_path / "other_uncertainty.png").exists()
    assert main(["--images", str(chessboards / "opencv-left"), "--out", str(out),
                 "--force", "-q"]) == 0
    assert (tmp_path / "left_report.html").exists()
    # Never overwrite without --force.
    before = out.read_bytes()
    assert main(["--images", str(chessboards / "opencv-left"), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert out.read_bytes() == before
    assert main(["--images", str(chessboards / "opencv-left"), "--out", str(out), "--force",
                 "-q"]) == 0


def test_cli_on_awkward_udacity_set(tmp_path, chessboards, capsys):
    folder = str(chessboards / "udacity-lane-9x6")
    assert main(["--images", folder, "--out", str(tmp_path / "u.yaml")]) == 2
    err = capsys.readouterr().err
    assert "different sizes: 1280x720 (18), 1281x721 (2)" in err
    assert main(["--images", folder, "--out", str(tmp_path / "u.yaml"), "--skip-other-sizes",
                 "-v"]) == 0
    captured = capsys.readouterr()
    assert "calibration15.jpg, calibration7.jpg" in captured.err
    assert "calibration1.jpg: board not found" in captured.err
    assert "calibration4.jpg: 54 corners (sector)" in captured.err
    # Said without -v too: which photos did not count.
    assert ("the board was not found in 2 of the 18 photos, left out: calibration1.jpg, "
            "calibration5.jpg") in captured.err
    camera = load_calibration(tmp_path / "u.yaml")
    assert camera.image_size == (1280, 720)
    assert 1100 < camera.K[0, 0] < 1250


def test_cli_video_collects_distinct_views(tmp_path, board_views, capsys):
    video = tmp_path / "board.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (640, 480),
                             isColor=False)
    assert writer.isOpened()
    for img in board_views:
        for _ in range(4):  # near-duplicate frames must be skipped
            writer.write(img)
    writer.release()
    out = tmp_path / "video.yaml"
    code = main(["--video", str(video), "--frames", "6", "--out", str(out),
                 "--save-undistorted", str(tmp_path / "und")])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    progress = [line for line in captured.err.splitlines() if line.startswith("view ")]
    assert len(progress) == 6 and progress[-1].startswith("view 6/6 from frame ")
    frames = [int(line.rsplit(" ", 1)[1]) for line in progress]
    # Each pose fills 4 frames: only its first frame can be a new view.
    assert all(f % 4 == 0 for f in frames) and len(set(frames)) == 6
    camera = load_calibration(out)
    assert abs(camera.K[0, 0] / TRUE_K[0, 0] - 1) < 0.01
    assert len(list((tmp_path / "und").glob("*.png"))) == 6
    assert "ended after" not in captured.err
    # Asking for more distinct views than the video holds: said, and calibrated on those.
    code = main(["--video", str(video), "--frames", "30", "--out", str(out), "--force",
                 "--no-report"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    views = sum(line.startswith("view ") for line in captured.err.splitlines())
    assert (f"the video ended after {4 * len(board_views)} frames with {views} of the 30 "
            "distinct views asked for") in captured.err


@pytest.mark.parametrize("case, message", [
    ("no_images", "no images found"),
    ("unreadable", "not an image file"),
    ("board_never_found", "check --board"),
    ("two_views", "found in only 2 of 2 views"),
    ("camera", "cannot open camera 99"),
    ("video_missing", "video not found"),
    ("out_folder_missing", "does not exist"),
    ("out_under_a_file", "is a file, not a folder"),
])
def test_cli_bad_inputs(tmp_path, chessboards, capsys, case, message):
    left = chessboards / "opencv-left"
    two = tmp_path / "two"
    two.mkdir()
    for name in ("left01.jpg", "left02.jpg"):
        shutil.copy(left / name, two / name)
    bad = tmp_path / "bad"
    bad.mkdir()
    shutil.copy(left / "left01.jpg", bad / "left01.jpg")
    (bad / "broken.jpg").write_text("not a jpeg")
    (tmp_path / "empty").mkdir()
    out = ["--out", str(tmp_path / "c.yaml")]
    argv = {
        "no_images": ["--images", str(tmp_path / "empty")],
        "unreadable": ["--images", str(bad)],
        "board_never_found": ["--images", str(left), "--board", "10x7"],  # squares counted
        "two_views": ["--images", str(two)],
        "camera": ["--camera", "99"],
        "video_missing": ["--video", str(tmp_path / "none.avi")],
        "out_folder_missing": ["--images", str(left), "--out", str(tmp_path / "x" / "c.yaml")],
        "out_under_a_file": ["--images", str(left), "--out",
                             str(bad / "left01.jpg" / "c.yaml")],
    }[case]
    if "--out" not in argv:
        argv += out
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "c.yaml").exists()


def test_calibrate_script_help():
    proc = subprocess.run([sys.executable, str(REPO / "calibrate.py"), "--help"],
                          capture_output=True, text=True)
    assert proc.returncode == 0
    for word in ("--images", "--video", "--camera", "--board", "--square-size", "--pattern",
                 "--frames", "--force", "--save-undistorted", "Exit codes"):
        assert word in proc.stdout
