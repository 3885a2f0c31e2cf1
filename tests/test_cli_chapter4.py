"""chapter4.py end to end, as a user runs it: a subprocess, files and exit codes."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from scene3D.evaluation import relative_pose_error
from scene3D.geometry import angle_between_deg
from scene3D.geometry.camera import scale_intrinsics
from scene3D.io.calibration import CameraCalibration, save_calibration
from scene3D.io.datasets import read_strecha_camera, relative_pose
from scene3D.io.export import read_ply

from .conftest import REPO
from .helpers import ROUNDS, counts_page_faults, run_python


def run(args, cwd, env=None, data_root=None):
    full_env = dict(os.environ, **(env or {}))
    if data_root is not None:
        full_env["SCENE3D_DATA"] = str(data_root)
    return subprocess.run([sys.executable, str(REPO / "chapter4.py"), *map(str, args)],
                          cwd=cwd, env=full_env, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def synthetic_files(tmp_path_factory, rendered_pair, rotated_pair):
    folder = tmp_path_factory.mktemp("synthetic")
    img1, img2, K, R, t = rendered_pair
    cv2.imwrite(str(folder / "a.png"), img1)
    cv2.imwrite(str(folder / "b.png"), img2)
    cv2.imwrite(str(folder / "rot.png"), rotated_pair[1])
    cv2.imwrite(str(folder / "small.png"), cv2.resize(img2, (320, 240)))
    cv2.imwrite(str(folder / "blank.png"), np.full_like(img1, 128))
    save_calibration(folder / "camera.yaml", CameraCalibration(K, np.zeros(5), (640, 480)))
    # The same camera calibrated at twice the resolution: K must be scaled down.
    K2 = scale_intrinsics(K, 2.0, 2.0)
    save_calibration(folder / "camera_2x.yaml", CameraCalibration(K2, np.zeros(5), (1280, 960)))
    save_calibration(folder / "camera_wide.yaml", CameraCalibration(K, np.zeros(5), (640, 360)))
    return folder


def test_default_run_is_the_book_pair_against_ground_truth(tmp_path, data_root):
    proc = run(["--out", tmp_path / "out"], cwd=tmp_path, data_root=data_root)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "out"
    names = {"optic_flow.png", "epipolar_lines.png", "rectified.png", "point_cloud.png",
             "point_cloud.ply", "cameras.json", "reconstruction.json", "report.html"}
    assert {p.name for p in out.iterdir()} == names | {"colmap"}
    for name in [*names, "colmap/cameras.txt", "colmap/images.txt", "colmap/points3D.txt"]:
        assert f"Wrote '{out / name}'" in proc.stdout
    # The pair's COLMAP model is of the photos as they are (3072x2048, not the working
    # 768x512), camera 2 at the reconstructed pose.
    from scene3D.io.colmap import read_colmap_text

    model = read_colmap_text(out / "colmap")
    assert model.names == ("0004.jpg", "0005.jpg")
    assert model.camera(0).image_size == (3072, 2048)
    summary = json.loads((out / "reconstruction.json").read_text())
    gt = data_root / "fountain-P11" / "gt_dense_cameras"
    cam4, cam5 = (read_strecha_camera(gt / f"000{i}.jpg.camera") for i in (4, 5))
    err = relative_pose_error(np.array(summary["R"]), np.array(summary["t"]),
                              *relative_pose(cam4, cam5))
    assert err.rotation_deg < 1.0 and err.translation_deg < 3.0
    assert summary["image_size"] == [768, 512]
    np.testing.assert_allclose(model.R[1], summary["R"], atol=1e-9)
    np.testing.assert_allclose(model.t[1], summary["t"], atol=1e-9)
    np.testing.assert_allclose(summary["K"], scale_intrinsics(cam4.K, 0.25, 0.25))
    assert summary["feature"] == "SIFT"
    assert summary["num_inliers"] <= summary["num_matches"]
    assert summary["robust_starts"] == 2 and summary["trusted"]  # confirmed at once
    # Both starts reached the same optimum (confirmation: unit-norm E entries within 1e-4).
    assert summary["robust_spread_deg"] < 5e-3
    assert abs(summary["focal_scale"] - 1.0) < 0.05 and 0 < summary["focal_scale_sigma"] < 0.05
    assert summary["reprojection_rmse_px"] < 0.5
    # The pose's uncertainty, and the error within its 3-sigma bound (the Strecha cameras
    # are themselves accurate to a few hundredths of a degree; the book pair's error is
    # within that bound).
    cov = np.array(summary["pose_covariance"])
    basis = np.array(summary["pose_covariance_basis"])
    assert cov.shape == (5, 5) and np.allclose(cov, cov.T) and basis.shape == (2, 3)
    np.testing.assert_allclose(basis @ np.array(summary["t"]), 0.0, atol=1e-12)
    assert summary["rotation_sigma_deg"] == pytest.approx(
        np.degrees(np.sqrt(np.linalg.eigvalsh(cov[:3, :3])[-1])))
    assert summary["translation_sigma_deg"] == pytest.approx(
        np.degrees(np.sqrt(np.linalg.eigvalsh(cov[3:, 3:])[-1])))
    assert 0 < summary["rotation_sigma_deg"] < 0.1 and 0 < summary["translation_sigma_deg"] < 0.2
    assert err.translation_deg < 3 * summary["translation_sigma_deg"] + 0.05
    assert "pose_covariance in radians^2" in summary["conventions"]
    assert 0.03 < summary["noise_sigma_px"] < 0.5
    assert {"features", "matching", "geometry", "plots", "total"} <= set(summary["timings_s"])
    assert summary["inputs"]["image1"].endswith("0004.jpg")
    points, colors = read_ply(out / "point_cloud.ply")
    assert len(points) == summary["num_points"] > 200
    assert colors.shape == (len(points), 3)
    assert np.all(points[:, 2] > 0)  # in front of camera 1
    # The printed centre of camera 2 is where the truth puts it, in camera 1's frame.
    printed = re.search(r"centre at \(([-+.\d]+), ([-+.\d]+), ([-+.\d]+)\) in camera 1's frame",
                        proc.stdout)
    R_true, t_true = relative_pose(cam4, cam5)
    assert angle_between_deg([float(v) for v in printed.groups()], -R_true.T @ t_true) < 3.0
    # The printed 1-sigma uncertainty is the JSON's, rounded.
    sigmas = re.search(r"pose uncertainty \(1 sigma\): rotation \+-([.\d]+) deg, translation "
                       r"direction \+-([.\d]+) deg", proc.stdout)
    assert float(sigmas.group(1)) == pytest.approx(summary["rotation_sigma_deg"], abs=6e-4)
    assert float(sigmas.group(2)) == pytest.approx(summary["translation_sigma_deg"], abs=6e-4)


def test_synthetic_pair_with_calibration_file(tmp_path, synthetic_files, rendered_pair):
    _, _, _, R, t = rendered_pair
    f = synthetic_files
    proc = run([f / "a.png", f / "b.png", "--calib", f / "camera_2x.yaml", "--no-plots",
                "--feature", "akaze", "--out", tmp_path / "o"], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "o" / "reconstruction.json").read_text())
    err = relative_pose_error(np.array(summary["R"]), np.array(summary["t"]), R, t)
    assert err.rotation_deg < 0.2 and err.translation_deg < 1.0
    assert summary["feature"] == "AKAZE"
    assert not list((tmp_path / "o").glob("*.png"))


def test_surf_falls_back_with_a_warning(tmp_path, synthetic_files):
    f = synthetic_files
    proc = run([f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--no-plots",
                "--feature", "surf", "--out", tmp_path], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "reconstruction.json").read_text())
    assert summary["feature_requested"] == "surf"
    if summary["feature"] == "SIFT":
        assert "SURF is patented" in proc.stderr


def _scene3d_command():
    """The installed ``scene3d`` console script, else ``python -m scene3D`` (same entry point)."""
    script = Path(sys.executable).parent / "scene3d"
    return [str(script)] if script.exists() else [sys.executable, "-m", "scene3D"]


def test_console_script_reconstruct(tmp_path, synthetic_files):
    f = synthetic_files
    proc = subprocess.run(
        [*_scene3d_command(), "reconstruct", f / "a.png", f / "b.png", "--calib",
         f / "camera.yaml", "--no-plots", "-q", "--out", tmp_path],
        capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == f"Wrote '{tmp_path / 'reconstruction.json'}'"
    assert (tmp_path / "point_cloud.ply").exists()
    help_proc = subprocess.run([*_scene3d_command(), "--help"], capture_output=True, text=True)
    assert help_proc.returncode == 0 and "reconstruct" in help_proc.stdout
    bad = subprocess.run([*_scene3d_command(), "explode"], capture_output=True, text=True)
    assert bad.returncode == 2 and "unknown command 'explode'" in bad.stderr


def _run_with_stdout_closed(args):
    """``args`` run with stdout a pipe whose reader has gone (``... | head -1`` once
    ``head`` has its line): every write to stdout fails with EPIPE."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        return subprocess.run([*map(str, args)], stdout=write_end, stderr=subprocess.PIPE,
                              text=True, timeout=300)
    finally:
        os.close(write_end)


@pytest.mark.parametrize("args", [["--help"], ["--version"], ["reconstruct", "--help"],
                                  ["reconstruct-views", "--help"], ["evaluate", "--help"],
                                  ["calibrate", "--help"], ["run"]])
def test_a_closed_stdout_ends_the_command_quietly(tmp_path, synthetic_files, args):
    """`scene3d --help | head -1`: no BrokenPipeError traceback, no "error: Broken pipe"
    (exit code 2, as if the input were wrong); the command ends with 141 (128 + SIGPIPE),
    the files of a run written all the same."""
    f = synthetic_files
    if args == ["run"]:  # results printed on stdout at the end of a reconstruction
        args = ["reconstruct", f / "a.png", f / "b.png", "--calib", f / "camera.yaml",
                "--no-plots", "--out", tmp_path]
    proc = _run_with_stdout_closed([*_scene3d_command(), *args])
    assert proc.stderr == ""
    if args[-1] == "--help" and args[0] != "--help":
        # argparse itself drops a help it cannot write (exit code 0) unless it is short
        # enough to wait in stdout's buffer, whose flush then fails in run_script
        assert proc.returncode in (0, 141)
    else:
        assert proc.returncode == 141  # scene3D.cli.EXIT_STDOUT_CLOSED
    if args[0] == "reconstruct" and args[-1] != "--help":
        assert (tmp_path / "reconstruction.json").exists()


@pytest.mark.parametrize("case, code, message", [
    ("missing", 2, "image not found"),
    ("folder", 2, "a folder, not an image file"),
    ("text", 2, "not an image file"),
    ("empty", 2, "the file is empty"),
    # With --calib or without, one message; it offers no --calib (which refuses them too).
    ("sizes", 2, "small.png' is 320x240 but '" + "...: photos of one camera at one size are "
                 "needed; one was resized: use the camera's originals, or resize the larger to "
                 "320x240\n"),
    ("bad_yaml", 2, "calibration file"),
    ("calib_missing", 2, "calibration file not found: '"),
    ("calib_folder", 2, "a folder, not a calibration file: '"),
    ("no_matrix", 2, "no 'camera_matrix'"),
    ("scalar_matrix", 2, "no 'camera_matrix' matrix"),
    ("width_half", 2, "whole numbers of pixels"),
    ("width_inf", 2, "whole numbers of pixels"),
    ("width_text", 2, "whole numbers of pixels"),
    ("far_principal_point", 2, "lies far outside the 640x480 image"),
    ("skew", 2, "skew of 3000"),
    ("aspect", 2, "images are 640x480 but the calibration is for 640x360, another aspect "
                  "ratio: cropped images, or another camera's?"),
    ("turned", 2, "images are 640x480 but the calibration is for 480x640: the images are "
                  "turned by 90 degrees from it (landscape against portrait); turn them back "
                  "to portrait"),
    ("out_is_file", 2, "is not a folder"),
    ("sizes_no_calib", 2, "error: '" + "...small.png' is 320x240 but '" + "...a.png' is "
                          "640x480: photos of one camera at one size are needed; one was "
                          "resized: use the camera's originals, or resize the larger to "
                          "320x240\n"),
    ("one_image", 2, "exactly two images"),
    ("same_image", 2, "image given twice"),
    ("hard_link", 2, "image given twice"),
    ("copy", 2, "are the same photo (the same pixels): a pair needs two views"),
    ("bad_option_value", 2, "error: argument --max-width: must be at least 1, got 0 (see "),
    ("empty_out", 2, "error: argument --out: must name a file or folder, got ''"),
    ("non_utf8_name", 2, "is not valid UTF-8 (from another system?): rename it"),
    ("non_utf8_out", 2, "argument --out: the name"),
    ("rotation", 1, "pure rotation"),
    ("blank", 1, "image 2 has no keypoints"),
    ("blank_no_calib", 1, "image 2 has no keypoints"),
])
def test_bad_inputs_exit_codes_and_messages(tmp_path, synthetic_files, case, code, message):
    f = synthetic_files
    calib = f / "camera.yaml"
    (tmp_path / "text.jpg").write_text("hello")
    (tmp_path / "empty.jpg").touch()
    (tmp_path / "bad.yaml").write_text("camera_matrix: [1, 2\n  : :")
    (tmp_path / "nomatrix.yaml").write_text("%YAML:1.0\n---\nimage_width: 640\n")
    (tmp_path / "file").write_text("x")
    os.link(f / "a.png", tmp_path / "linked.png")  # the same file under another name
    shutil.copy(f / "a.png", tmp_path / "copy.png")  # the same pixels in another file
    shutil.copy(f / "b.png", tmp_path / os.fsdecode(b"b\xe9.png"))  # Latin-1 bytes
    matrix = ("camera_matrix: !!opencv-matrix\n  rows: 3\n  cols: 3\n  dt: d\n"
              "  data: [500., {skew}, {cx}, 0., 500., 240., 0., 0., 1.]\n")
    for name, head, width in (("scalar", "camera_matrix: 5.0\n", "640"),
                              ("half", matrix.format(skew=0, cx=320), "0.5"),
                              ("inf", matrix.format(skew=0, cx=320), ".Inf"),
                              ("text", matrix.format(skew=0, cx=320), "abc"),
                              ("far", matrix.format(skew=0, cx=-50000), "640"),
                              ("skew", matrix.format(skew=3000, cx=320), "640")):
        (tmp_path / f"{name}.yaml").write_text(
            f"%YAML:1.0\n---\n{head}image_width: {width}\nimage_height: 480\n")
    # The camera held upright: a calibration of portrait images, 480x640.
    save_calibration(tmp_path / "turned.yaml", CameraCalibration(
        np.array([[500.0, 0.0, 239.5], [0.0, 500.0, 319.5], [0.0, 0.0, 1.0]]), np.zeros(5),
        (480, 640)))
    args = {
        "missing": [tmp_path / "nope.jpg", f / "b.png", "--calib", calib],
        "folder": [f, f / "b.png", "--calib", calib],
        "text": [tmp_path / "text.jpg", f / "b.png", "--calib", calib],
        "empty": [f / "a.png", tmp_path / "empty.jpg", "--calib", calib],
        "sizes": [f / "a.png", f / "small.png", "--calib", calib],
        "bad_yaml": [f / "a.png", f / "b.png", "--calib", tmp_path / "bad.yaml"],
        "calib_missing": [f / "a.png", f / "b.png", "--calib", tmp_path / "nope.yaml"],
        "calib_folder": [f / "a.png", f / "b.png", "--calib", f],
        "no_matrix": [f / "a.png", f / "b.png", "--calib", tmp_path / "nomatrix.yaml"],
        "aspect": [f / "a.png", f / "b.png", "--calib", f / "camera_wide.yaml"],
        "turned": [f / "a.png", f / "b.png", "--calib", tmp_path / "turned.yaml"],
        "scalar_matrix": [f / "a.png", f / "b.png", "--calib", tmp_path / "scalar.yaml"],
        "width_half": [f / "a.png", f / "b.png", "--calib", tmp_path / "half.yaml"],
        "width_inf": [f / "a.png", f / "b.png", "--calib", tmp_path / "inf.yaml"],
        "width_text": [f / "a.png", f / "b.png", "--calib", tmp_path / "text.yaml"],
        "far_principal_point": [f / "a.png", f / "b.png", "--calib", tmp_path / "far.yaml"],
        "skew": [f / "a.png", f / "b.png", "--calib", tmp_path / "skew.yaml"],
        "out_is_file": [f / "a.png", f / "b.png", "--calib", calib, "--out", tmp_path / "file"],
        "sizes_no_calib": [f / "a.png", f / "small.png"],
        "one_image": [f / "a.png", "--calib", calib],
        "same_image": [f / "a.png", f / ".." / f.name / "a.png", "--calib", calib],
        "hard_link": [f / "a.png", tmp_path / "linked.png", "--calib", calib],
        "copy": [f / "a.png", tmp_path / "copy.png", "--calib", calib],
        "bad_option_value": [f / "a.png", f / "b.png", "--max-width", "0"],
        "empty_out": [f / "a.png", f / "b.png", "--out", ""],
        "non_utf8_name": [f / "a.png", tmp_path / os.fsdecode(b"b\xe9.png"), "--calib", calib],
        "non_utf8_out": [f / "a.png", f / "b.png", "--out", tmp_path / os.fsdecode(b"o\xe9")],
        "rotation": [f / "a.png", f / "rot.png", "--calib", calib],
        "blank": [f / "a.png", f / "blank.png", "--calib", calib],
        "blank_no_calib": [f / "a.png", f / "blank.png"],
    }[case]
    if "--out" not in args:
        args += ["--out", tmp_path / "out"]
    proc = run(args + ["--no-plots"], cwd=tmp_path)
    assert proc.returncode == code
    assert all(part in proc.stderr for part in message.split("..."))
    assert "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out" / "reconstruction.json").exists()


def test_debug_shows_the_traceback(tmp_path, synthetic_files):
    f = synthetic_files
    proc = run([tmp_path / "nope.jpg", f / "b.png", "--calib", f / "camera.yaml", "--debug"],
               cwd=tmp_path)
    assert proc.returncode != 0 and "Traceback" in proc.stderr


def test_offline_without_data_is_one_clear_error(tmp_path):
    env = {"SCENE3D_DATA": str(tmp_path / "none"), "SCENE3D_CACHE": str(tmp_path / "cache"),
           "SCENE3D_DATA_URL": "http://127.0.0.1:9/offline"}
    proc = run(["--out", tmp_path / "out"], cwd=tmp_path, env=env)
    assert proc.returncode == 2
    assert "SCENE3D_DATA" in proc.stderr and "two photos of your own" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_help_explains_the_outputs():
    proc = subprocess.run([sys.executable, str(REPO / "chapter4.py"), "--help"],
                          capture_output=True, text=True)
    assert proc.returncode == 0
    for word in ("--calib", "--feature", "--no-pyr-down", "--max-width", "--out", "--no-plots",
                 "--no-report", "report.html", "--show", "reconstruction.json", "Exit codes"):
        assert word in " ".join(proc.stdout.split())


def test_dense_outputs(tmp_path, synthetic_files):
    f = synthetic_files
    proc = run([f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--dense",
                "--out", tmp_path], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "reconstruction.json").read_text())
    points, colors = read_ply(tmp_path / "dense.ply")
    assert len(points) == summary["dense"]["num_points"] > 50_000
    assert (tmp_path / "disparity.png").read_bytes().startswith(b"\x89PNG")
    assert "dense" in summary["timings_s"]
    # The report's 3D view holds both clouds.
    report = (tmp_path / "report.html").read_text()
    assert f'"name":"dense ({summary["dense"]["num_points"]:,})"' in report
    assert f'"name":"sparse ({summary["num_points"]:,})"' in report


def test_show_without_a_display_warns_and_still_writes(tmp_path, synthetic_files):
    f = synthetic_files
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run([sys.executable, str(REPO / "chapter4.py"), f / "a.png", f / "b.png",
                           "--calib", f / "camera.yaml", "--show", "--out", tmp_path],
                          env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "no display available" in proc.stderr
    assert (tmp_path / "point_cloud.png").exists()


def test_max_width_halves_images_and_scales_K(tmp_path, synthetic_files, rendered_pair):
    f = synthetic_files
    K = rendered_pair[2]
    proc = run([f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--max-width", "400",
                "--no-plots", "--out", tmp_path], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "reconstruction.json").read_text())
    assert summary["image_size"] == [320, 240]
    np.testing.assert_allclose(summary["K"], scale_intrinsics(K, 0.5, 0.5))
    both = run([f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--max-width", "400",
                "--no-pyr-down"], cwd=tmp_path)
    assert both.returncode == 2 and "not allowed with" in both.stderr
    for bad in ("0", "-5", "wide"):
        proc = run([f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--max-width", bad],
                   cwd=tmp_path)
        assert proc.returncode == 2 and "--max-width: must be" in proc.stderr


def test_startup_imports_nothing_heavy_before_the_cli_sets_up_blas():
    """`import scene3D` loads neither numpy nor OpenCV; the CLI package sets the OpenBLAS
    spin timeout before they load, and keeps a value the user chose."""
    code = ("import os, sys, scene3D; heavy = {'numpy', 'cv2'} & set(sys.modules); "
            "import scene3D.cli; print(sorted(heavy), os.environ['OPENBLAS_THREAD_TIMEOUT'])")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.split()
    assert out == ["[]", "4"]
    env["OPENBLAS_THREAD_TIMEOUT"] = "10"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.split()
    assert out == ["[]", "10"]


@counts_page_faults
def test_the_scripts_keep_freed_memory_unless_the_user_tuned_malloc():
    """A script's process (run_script: chapter4.py, calibrate.py, scene3d) lets malloc
    reuse a freed 24 MB block (SIFT's largest level at 1536 px is 25 MB): allocated
    again, it faults in no fresh pages. Importing the CLI alone changes nothing (a test
    or a library user's process), and a malloc setting of the user's is kept."""
    script = ROUNDS + ("import scene3D.cli, sys\n"
                       "def body(): rounds(1, 24); return 0\n"
                       "scene3D.cli.run_script(body) if sys.argv[1:] else body()\n")

    def faults(*args: str, **extra_env: str) -> list[int]:
        return [int(n) for n in run_python(script, *args, **extra_env)]

    first, *again = faults("script")
    assert first > 5000 and max(again) < 100  # 6144 pages of 4 KiB, then reused
    assert faults()[1] > 5000  # imported only: glibc's defaults map it afresh once more
    assert min(faults("script", MALLOC_MMAP_THRESHOLD_="131072")) > 5000  # the user's


def test_reconstruct_views_runs_blas_on_one_thread_unless_told():
    """`scene3d reconstruct-views` sets OpenBLAS to one thread before numpy loads (its
    bundle adjustment ran ten times slower on two threads beside another busy program);
    a value the user chose is kept, and the other commands are left alone."""
    code = ("import os, sys; from scene3D.cli import main; main(sys.argv[1:]); "
            "print(os.environ.get('OPENBLAS_NUM_THREADS'))")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}

    def threads(*args, **extra):
        return subprocess.run([sys.executable, "-c", code, *args, "--help"],
                              env={**env, **extra}, capture_output=True, text=True,
                              check=True).stdout.split()[-1]

    assert threads("reconstruct-views") == "1"
    assert threads("reconstruct-views", OPENBLAS_NUM_THREADS="2") == "2"
    assert threads("evaluate") == "None"


def test_the_scripts_exit_keeps_the_code_and_the_exit_handlers():
    """`exit_process` (the scripts' end: Python's last collections skipped) still exits
    with the command's code, runs atexit handlers and flushes what was printed."""
    code = ("import atexit, sys; from scene3D.cli import exit_process; "
            "atexit.register(lambda: print('handler ran')); print('output', end=''); "
            "sys.stdout.write(' kept\\n'); exit_process(3)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 3
    assert proc.stdout.split() == ["output", "kept", "handler", "ran"]


@pytest.mark.parametrize("module", ["chapter4", "calibrate", "evaluate", "multiview",
                                    "dense_views"])
def test_every_argument_of_every_command_has_help(module):
    import argparse
    import importlib

    parser = importlib.import_module(f"scene3D.cli.{module}").build_parser()
    silent = [action.dest for action in parser._actions
              if not action.help and not isinstance(action, argparse._HelpAction)]
    assert silent == []
    # An option with a default says which ('--pairs' did not).
    unsaid = [action.dest for action in parser._actions
              if action.option_strings and action.default not in (None, False, argparse.SUPPRESS)
              and not isinstance(action, (argparse._HelpAction, argparse._CountAction))
              and "default" not in action.help]
    assert unsaid == []


def test_a_still_camera_before_a_moving_board_gives_no_trusted_pose(tmp_path, chessboards, capsys):
    """OpenCV's left*.jpg: the camera stood still while the board was moved. A pair where
    the board barely moved is a pure rotation; where it moved, its matches look like
    parallax to a rigid model. Either is refused, or the pose comes back flagged."""
    from scene3D.cli.chapter4 import main

    folder = chessboards / "opencv-left"
    calib = folder / "left_intrinsics.yml"  # OpenCV's own calibration of these photos
    names = ["left01.jpg", "left04.jpg", "left08.jpg", "left12.jpg"]
    for k, (a, b) in enumerate((a, b) for i, a in enumerate(names) for b in names[i + 1:]):
        out = tmp_path / f"out{k}"
        code = main([str(folder / a), str(folder / b), "--calib", str(calib), "--no-plots",
                     "--no-report", "--out", str(out), "-q"])
        err = capsys.readouterr().err
        assert code in (0, 1), (a, b, err)
        if code == 0:
            assert not json.loads((out / "reconstruction.json").read_text())["trusted"], (a, b)
        else:
            assert "error:" in err and not (out / "reconstruction.json").exists(), (a, b, err)


def test_dense_on_a_pair_it_cannot_rectify_fails_in_one_line(tmp_path, chessboards, capsys):
    """left04/left08: the board moved before a still camera, so the epipole lies in the
    image and the rectified disparities span [-337, 2591) px on 640 px (SGBM failed to
    allocate 2^64 bytes before). Exit 1, nothing written; without --dense a result."""
    from scene3D.cli.chapter4 import main

    folder = chessboards / "opencv-left"
    args = [str(folder / "left04.jpg"), str(folder / "left08.jpg"),
            "--calib", str(folder / "left_intrinsics.yml"), "--no-plots", "--no-report", "-q"]
    out = tmp_path / "out"
    assert main(args + ["--dense", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: dense matching cannot serve this pair") and "\n" not in err
    assert "run without --dense" in err
    assert not out.exists()  # the folder it created, removed again
    assert main(args + ["--out", str(out)]) == 0


def test_a_run_replaces_the_previous_runs_files_and_keeps_the_users(tmp_path, synthetic_files):
    """The second run writes no figures and no report: the first run's go with the rest of
    its results, the user's file stays, and reconstruction.json lists what is there."""
    f = synthetic_files
    out = tmp_path / "out"
    args = [f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--out", out]
    assert run(args, cwd=tmp_path).returncode == 0
    first = json.loads((out / "reconstruction.json").read_text())["files"]
    assert "report.html" in first and "point_cloud.png" in first
    assert sorted({n.split("/")[0] for n in first}) == sorted(p.name for p in out.iterdir())
    (out / "notes.txt").write_text("mine")
    proc = run(args + ["--no-plots", "--no-report"], cwd=tmp_path)
    assert proc.returncode == 0
    assert f"Removed '{out / 'report.html'}' (an earlier run's, not written again)" in proc.stdout
    second = json.loads((out / "reconstruction.json").read_text())["files"]
    assert second == ["cameras.json", "colmap/cameras.txt", "colmap/images.txt",
                      "colmap/points3D.txt", "point_cloud.ply", "reconstruction.json"]
    assert sorted(p.name for p in out.iterdir()) == ["cameras.json", "colmap", "notes.txt",
                                                     "point_cloud.ply", "reconstruction.json"]


def test_a_reconstruction_json_of_someone_else_is_not_replaced(tmp_path, synthetic_files):
    f = synthetic_files
    (tmp_path / "reconstruction.json").write_text('{"my": "data"}')
    proc = run([f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--out", tmp_path,
                "--no-plots", "--no-report"], cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip() == (f"error: '{tmp_path / 'reconstruction.json'}' was not "
                                   "written by scene3D and would be replaced; choose another "
                                   "--out")
    assert (tmp_path / "reconstruction.json").read_text() == '{"my": "data"}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reconstruction.json"]


def test_an_out_folder_from_before_the_file_list_keeps_working(tmp_path, synthetic_files):
    """A reconstruction.json without "files" (scene3D before 2026-12-03): its figures and
    report are taken as that run's, so a run without them removes them, and the next run
    with them is not refused."""
    f = synthetic_files
    out = tmp_path / "out"
    args = [f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--out", out, "-q"]
    assert run(args, cwd=tmp_path).returncode == 0
    summary = json.loads((out / "reconstruction.json").read_text())
    del summary["files"]
    (out / "reconstruction.json").write_text(json.dumps(summary))
    proc = run(args + ["--no-plots", "--no-report"], cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert f"Removed '{out / 'report.html'}'" in proc.stdout
    assert sorted(p.name for p in out.iterdir()) == ["cameras.json", "colmap", "point_cloud.ply",
                                                     "reconstruction.json"]
    proc = run(args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr


def test_a_file_of_the_users_named_like_an_output_is_not_replaced(tmp_path, synthetic_files):
    """--out holding the user's point_cloud.ply (no earlier run wrote it), or being the
    photos' folder where a photo is named like a figure: exit 2 before any work, every
    file as it was."""
    f = synthetic_files
    (tmp_path / "point_cloud.ply").write_text("the user's")
    shutil.copy(f / "b.png", tmp_path / "rectified.png")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    proc = run([f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--out", tmp_path,
                "--no-plots", "--no-report"], cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip() == (
        f"error: --out '{tmp_path}' holds '{tmp_path / 'point_cloud.ply'}', which no earlier "
        "scene3D run there wrote, and the run would replace it; move it or choose another --out")
    (tmp_path / "point_cloud.ply").unlink()
    del before["point_cloud.ply"]
    proc = run([f / "a.png", tmp_path / "rectified.png", "--calib", f / "camera.yaml",
                "--out", tmp_path], cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip() == (
        f"error: --out '{tmp_path}': the run would write '{tmp_path / 'rectified.png'}', one "
        "of its inputs; choose another folder for the outputs")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_a_write_that_fails_leaves_the_previous_run_whole(tmp_path, synthetic_files):
    """A folder where report.html goes: refused before any file is replaced."""
    f = synthetic_files
    out = tmp_path / "out"
    args = [f / "a.png", f / "b.png", "--calib", f / "camera.yaml", "--out", out, "--no-plots"]
    assert run(args + ["--no-report"], cwd=tmp_path).returncode == 0
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    (out / "report.html").mkdir()
    proc = run(args + ["--feature", "akaze"], cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip() == (f"error: a folder stands where this file is to be written: "
                                   f"'{out / 'report.html'}'")
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before  # the earlier point cloud, model and JSON, no temporary file


def test_warnings_are_printed_also_when_they_leave_the_pose_trusted():
    """A result's warnings are logged marked as the result's (the command drops those
    records) and printed with it: all in one line when the pose is doubted, each on its
    own when it stays trusted (a focal length kept from EXIF)."""
    from scene3D.cli.chapter4 import warning_lines

    kept = "the photos do not determine the focal length better than the EXIF value"
    assert warning_lines(True, (kept,)) == [f"warning: {kept}"]
    assert warning_lines(True, ()) == []
    assert warning_lines(False, ("a", "b")) == [
        "warning: the pose may not be trustworthy: a; b"]
