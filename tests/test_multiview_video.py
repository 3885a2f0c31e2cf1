"""Views from a video (scene3D.multiview.video and ``reconstruct-views VIDEO``): a rendered
orbit written as an MP4 with some frames blurred; the frames kept, the bound on their
count, and the reconstruction of the kept frames against the true cameras."""

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest

from scene3D.calibration.views import frame_time_name, read_frames
from scene3D.cli import multiview
from scene3D.evaluation import camera_set_error
from scene3D.evaluation.synthetic import orbit_poses, orbit_scene, render_planes
from scene3D.geometry.conventions import rotation_error_deg
from scene3D.multiview.video import MIN_MOTION, select_frames

from .conftest import REPO

#: Square pixels (as a video has), the principal point a little off the centre.
K_TRUE = np.array([[600.0, 0, 322.0], [0, 600.0, 237.0], [0, 0, 1]])
FRAMES, FPS = 60, 10
#: Frames blurred as a shaking hand blurs them (Gaussian sigma in px), two in a row once.
BLURRED = {9: 3.0, 10: 2.0, 23: 2.0, 37: 1.5, 50: 2.5}


@pytest.fixture(scope="module")
def orbit_video(tmp_path_factory):
    """Sixty frames 2 deg apart along a third of the courtyard's orbit, as an MP4 at 10
    frames per second; the true poses of every frame."""
    Rs, ts = orbit_poses(180)
    Rs, ts = Rs[:FRAMES], ts[:FRAMES]
    scene = orbit_scene()
    path = tmp_path_factory.mktemp("video") / "orbit.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), FPS, (640, 480))
    for k, (R, t) in enumerate(zip(Rs, ts)):
        image = render_planes(K_TRUE, R, t, rectangles=scene, supersample=1)[0]
        if k in BLURRED:
            image = cv2.GaussianBlur(image, (0, 0), BLURRED[k])
        writer.write(image)
    writer.release()
    return path, Rs, ts


def _index(name: str) -> int:
    """The frame a time name stands for ('t001.20s' -> 12 at 10 frames per second)."""
    return round(float(name[1:-1]) * FPS)


def test_frames_are_named_by_their_time(orbit_video):
    path, _, _ = orbit_video
    names = [name for name, _ in read_frames(path, timed=True)]
    assert len(names) == FRAMES
    assert names[:3] == ["t000.00s", "t000.10s", "t000.20s"]
    assert [_index(n) for n in names] == list(range(FRAMES))
    assert frame_time_name(12.4) == "t012.40s" and frame_time_name(1234.5) == "t1234.50s"


def test_sharp_frames_that_moved_are_kept(orbit_video):
    """No blurred frame is kept (each says it is blurred); the first is kept, then one
    each time the image moved 5 % of its diagonal: the true cameras of consecutive kept
    frames are 8 deg or more apart (the image moves about 0.4 % a degree here), and
    none of the sharp frames left out had moved that far."""
    path, Rs, _ = orbit_video
    chosen = select_frames(read_frames(path, timed=True), progress=lambda _: None)
    kept = [_index(n) for n in chosen.names]
    by_index = {_index(c.name): c for c in chosen.choices}
    assert len(by_index) == FRAMES and chosen.image_size == (640, 480)
    assert not set(kept) & set(BLURRED)
    assert all(by_index[k].reason.startswith("blurred") for k in BLURRED)
    assert kept[0] == 0 and 8 <= len(kept) <= 14
    assert kept[-1] >= FRAMES - 4  # the end of the video stays covered
    for a, b in zip(kept, kept[1:]):
        assert rotation_error_deg(Rs[a], Rs[b]) >= 8.0
        assert by_index[b].motion >= (MIN_MOTION if b != kept[-1] else MIN_MOTION / 2)
    left_out = [c for c in chosen.choices if c.reason.startswith("moved only")]
    assert left_out and all(c.motion < MIN_MOTION for c in left_out)
    counts = chosen.counts()
    assert counts["blurred"] == len(BLURRED) and counts["kept"] == len(kept)
    assert chosen.summary().startswith(f"{FRAMES} frames read, {len(kept)} kept")
    # As recorded: every frame read, its time, whether kept and why.
    record = json.loads(json.dumps(chosen.to_dict()))
    frames = record["frames"]
    assert [f["time_s"] for f in frames] == pytest.approx([k / FPS for k in range(FRAMES)])
    assert [round(f["time_s"] * FPS) for f in frames if f["kept"]] == kept
    assert all(frames[k]["reason"].startswith("blurred") and frames[k]["motion"] is None
               for k in BLURRED)
    assert frames[0]["reason"] == "first sharp frame" and record["counts"] == counts
    assert record["summary"] == chosen.summary() and record["image_size"] == [640, 480]


def test_the_count_is_bounded(orbit_video):
    """With room for 4 frames a file is thinned to cover the whole video (every other
    frame out, the spacing doubled); a stream (a webcam) stops at 4."""
    path, _, _ = orbit_video
    chosen = select_frames(read_frames(path, timed=True), max_frames=4,
                           progress=lambda _: None)
    kept = [_index(n) for n in chosen.names]
    assert 3 <= len(kept) <= 4 and kept[0] == 0 and kept[-1] >= FRAMES / 2
    assert chosen.min_motion >= 2 * MIN_MOTION and chosen.counts()["thinned"] > 0
    assert len(chosen.choices) == FRAMES and chosen.images[0].shape == (480, 640, 3)

    stream = select_frames(read_frames(path, timed=True), max_frames=4, stop_when_full=True,
                           progress=lambda _: None)
    assert len(stream.names) == 4 and len(stream.choices) < FRAMES / 2
    with pytest.raises(ValueError, match="max_frames"):
        select_frames(iter([]), max_frames=1)
    with pytest.raises(ValueError, match="no frames"):
        select_frames(iter([]))


def test_reconstruct_views_of_a_video(orbit_video, tmp_path, capsys):
    """``reconstruct-views VIDEO``: it says which frames it kept, registers all of them
    with cameras within 0.5 deg and 1 % of the true ones, names them by time, and
    --export nerfstudio writes the frames the transforms point to."""
    path, Rs, ts = orbit_video
    out = tmp_path / "out"
    code = multiview.main([str(path), "--out", str(out), "--no-plots", "--no-report",
                           "--export", "nerfstudio"])
    err = capsys.readouterr().err
    assert code == 0, err
    kept_lines = [line for line in err.splitlines() if line.startswith("kept t")]
    assert f"video '{path}': {FRAMES} frames read, {len(kept_lines)} kept" in err
    cameras = json.loads((out / "cameras.json").read_text())
    names = [line.split()[1].rstrip(":") for line in kept_lines]
    assert sorted(cameras) == sorted(names) and len(names) >= 8
    index = [_index(n) for n in names]
    R_est = np.array([cameras[n]["R"] for n in names])
    c_est = np.array([cameras[n]["center"] for n in names])
    centers = -np.einsum("vji,vj->vi", Rs[index], ts[index])
    error = camera_set_error(R_est, c_est, Rs[index], centers)
    assert error.rotation_errors_deg.max() < 0.5 and error.center_errors.max() < 0.01
    transforms = json.loads((out / "transforms.json").read_text())
    paths = sorted(frame["file_path"] for frame in transforms["frames"])
    assert paths == sorted(f"frames/{n}.png" for n in names)
    assert all(cv2.imread(str(out / p)).shape == (480, 640, 3) for p in paths)
    # reconstruction.json records the frames kept (their time and why) and those left out.
    video = json.loads((out / "reconstruction.json").read_text())["video"]
    assert video["source"] == str(path) and len(video["frames"]) == FRAMES
    kept = {f["name"]: f for f in video["frames"] if f["kept"]}
    assert sorted(kept) == sorted(names)
    assert all(kept[n]["time_s"] == pytest.approx(_index(n) / FPS) for n in names)
    reasons = {line.split(": ", 1)[0][len("kept "):]: line.split(": ", 1)[1]
               for line in kept_lines}
    assert {n: kept[n]["reason"] for n in names} == reasons
    assert all(not f["kept"] and f["reason"].startswith("blurred")
               for f in video["frames"] if _index(f["name"]) in BLURRED)


def test_undistorted_frames_beside_transforms(orbit_video, tmp_path):
    """--export nerfstudio --undistort: transforms.json names undistorted/NAME.png, each
    the frame undistorted with its camera in cameras.json, and says no distortion; no
    frames/ then. --undistort alone is a usage error."""
    path, _, _ = orbit_video
    out = tmp_path / "out"
    assert multiview.main([str(path), "--out", str(out), "--no-plots", "--no-report",
                           "--quiet", "--export", "nerfstudio", "--undistort"]) == 0
    assert not (out / "frames").exists()
    transforms = json.loads((out / "transforms.json").read_text())
    assert all(transforms[k] == 0 for k in ("k1", "k2", "p1", "p2"))
    cameras = json.loads((out / "cameras.json").read_text())
    assert sorted(f["file_path"] for f in transforms["frames"]) == sorted(
        f"undistorted/{n}.png" for n in cameras)
    frames = dict(read_frames(path, timed=True))
    for name, camera in cameras.items():
        K, dist = np.array(camera["K"]), np.array(camera["distortion"])
        assert transforms["fl_x"] == pytest.approx(K[0, 0])
        copy = cv2.imread(str(out / "undistorted" / f"{name}.png"))
        np.testing.assert_array_equal(copy, cv2.undistort(frames[name], K, dist, None, K))
    assert multiview.main([str(path), "--out", str(tmp_path / "o"), "--undistort"]) == 2
    assert not (tmp_path / "o").exists()


def test_a_file_that_is_not_a_video(tmp_path):
    """A text file named as a video: exit code 2 and one line (FFmpeg's own lines off)."""
    fake = tmp_path / "x.mp4"
    fake.write_text("not a video\n")
    proc = subprocess.run([sys.executable, "-m", "scene3D", "reconstruct-views", str(fake),
                           "--out", str(tmp_path / "out")], cwd=REPO, capture_output=True,
                          text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [f"error: cannot open video '{fake}'"]
    assert not (tmp_path / "out").exists()


def test_camera_or_images(tmp_path, capsys):
    """--camera with images, or neither: a one-line usage error."""
    assert multiview.main(["a.mp4", "--camera", "0", "--out", str(tmp_path / "o")]) == 2
    assert multiview.main(["--out", str(tmp_path / "o")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == ["error: give IMAGES or --camera, not both",
                     "error: give IMAGES (photos, a folder, a glob or a video) or --camera"]
