"""``scene3d reconstruct-views`` at its edges: a calibration that leaves no model or that
the views refute, photos of one name in two folders, ``--out`` among the photos, hidden
files in a folder, and names COLMAP's text format cannot hold."""

import dataclasses
import json
import re

import cv2
import numpy as np
import pytest

from scene3D.cli import dense_views, multiview
from scene3D.errors import ReconstructionError
from scene3D.io.calibration import CameraCalibration, save_calibration
from scene3D.io.colmap import colmap_model_from_views, colmap_text
from scene3D.io.datasets import read_strecha_camera
from scene3D.multiview import SfMSettings, mapper, reconstruct_views
from scene3D.multiview.settings import refutes_calibration

from .conftest import REPO

CALIB = str(REPO / "data" / "fountain_P11_intrinsics.yaml")


def _photos(folder, names, seed=0):
    """Small textured images (never reconstructed: the checks come first)."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    for name in names:
        cv2.imwrite(str(folder / name), rng.integers(0, 256, (60, 80, 3)).astype(np.uint8))
    return [folder / name for name in names]


@pytest.fixture
def no_reconstruction(monkeypatch):
    """The reconstruction replaced by a failure naming itself: a run that gets past the
    checks ends with 'error: reached the reconstruction' (exit code 1)."""
    def reached(*args, **kwargs):
        raise ReconstructionError("test", "reached the reconstruction")

    monkeypatch.setattr(multiview, "reconstruct_views", reached)


def _earlier_run(out):
    """An earlier run's files in ``out``: they must stay as they are."""
    out.mkdir(parents=True)
    files = {"points.ply": "earlier", "cameras.json": "{}",
             "reconstruction.json": json.dumps({"conventions": "x",
                                                "files": ["points.ply", "cameras.json",
                                                          "reconstruction.json"]})}
    for name, text in files.items():
        (out / name).write_text(text)
    return files


def _fail_under_focal_length(fountain, tmp_path, capsys, focal_px: float,
                             written_if_failed: bool = False) -> str:
    """reconstruct-views of fountain-P11 0004-0008 at 768 px with a calibration whose focal
    length is ``focal_px`` (the truth: 2759 px): exit 1 in one line, and an earlier run's
    files in ``--out`` as they were, unless ``written_if_failed`` and a model that failed
    its check was written for inspection. The line."""
    K = read_strecha_camera(fountain / "gt_dense_cameras" / "0004.jpg.camera").K.copy()
    K[0, 0] = K[1, 1] = focal_px
    calib = save_calibration(tmp_path / "wrong.yaml",
                             CameraCalibration(K, np.zeros(5), (3072, 2048)))
    images = [str(fountain / "images" / f"{i:04d}.jpg") for i in range(4, 9)]
    out = tmp_path / "out"
    earlier = _earlier_run(out)
    assert multiview.main([*images, "--calib", str(calib), "--max-width", "768", "--no-plots",
                           "-q", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    summary = json.loads((out / "reconstruction.json").read_text())
    if written_if_failed and summary.get("status") == "failed":
        assert "failed its consistency check" in err
    else:
        assert {p.name: p.read_text() for p in out.iterdir()} == earlier
    return err


def test_a_calibration_that_leaves_no_model_stops_in_one_line(fountain, tmp_path, capsys,
                                                              monkeypatch):
    """A focal length of 800 px, the run started from the best candidate pair as if the
    candidates' focal checks were not weighed (they stop it at the start: test below):
    the check takes the first model's views out, until one is left (before: on until
    none was, and an IndexError; all 11 views: one left, and an IndexError in the
    command), or until the model left fails its check (on another CPU's floating point);
    either way one line that says so and asks about the calibration, exit 1."""
    _start_from_the_best_candidate(monkeypatch)
    err = _fail_under_focal_length(fountain, tmp_path, capsys, 800.0, written_if_failed=True)
    assert (err.startswith("error: no model could be kept: the one started from views ")
            and "taken out because their poses contradicted the pair geometry" in err
            and "does the calibration fit these photos?" in err
            or err.startswith("error: the reconstruction failed its consistency check: ")
            and "is the calibration for this camera" in err), err


_REFUTED = re.compile(r"error: the candidate pairs to start from fit a focal length "
                      r"(\d+\.\d\d) times the calibration's \(the median of (\d+)")


@pytest.mark.parametrize("focal_px", [900.0, 600.0])
def test_a_calibration_the_start_pairs_refute_stops_at_the_start(fountain, tmp_path, capsys,
                                                                focal_px):
    """A focal length of 900 px (a third of the truth): one candidate pair was trusted
    under it, its own focal check passing, 14 deg off; grown from it, a model of three
    views came back with status ok, 10-12 deg off. At 600 px no candidate is trusted.
    Either way the candidate pairs whose matches tell the focal length refute the
    calibration, by a factor of at least 2, and the run stops at the start, in one line.
    (Which candidates triangulate or pass their own checks is left to the CPU's floating
    point: one machine counted 3 of 5 refuting at 900 px, another 4 of 5, a third 2 of
    4; with pairs that cannot tell counted against it, the third started from the wrong
    pair and lost its model.)"""
    err = _fail_under_focal_length(fountain, tmp_path, capsys, focal_px)
    refuted = _REFUTED.match(err)
    assert refuted, err
    factor, refuting = float(refuted.group(1)), int(refuted.group(2))
    assert 2.0 < factor < 1.2 * 2759.0 / focal_px and refuting >= 2
    assert "; does the calibration fit these photos?" in err


def test_photos_of_one_name_in_two_folders_are_refused(tmp_path, capsys, no_reconstruction):
    """day1/IMG_0000.jpg and day2/IMG_0000.jpg would be one key in cameras.json and one
    name twice in images.txt: refused before any work (exit 2), both paths named."""
    day1 = _photos(tmp_path / "day1", ["IMG_0000.jpg", "IMG_0001.jpg"])
    day2 = _photos(tmp_path / "day2", ["IMG_0000.jpg", "IMG_0002.jpg"])
    out = tmp_path / "out"
    assert multiview.main([str(tmp_path / "day1"), str(tmp_path / "day2"),
                           "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"error: two photos are named 'IMG_0000.jpg' ('{day1[0]}', '{day2[0]}'): the outputs "
        "name views by file name; rename one\n")
    assert not out.exists()
    # Two names that images.txt would write alike.
    _photos(tmp_path / "mixed", ["a b.jpg", "a_b.jpg"])
    assert multiview.main([str(tmp_path / "mixed"), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        "error: 'a_b.jpg' and 'a b.jpg' would both be 'a_b.jpg' in colmap/images.txt, which "
        "cannot hold spaces in names; rename one\n")
    # The library refuses them too: its result names views the same way.
    from scene3D.multiview import reconstruct_views

    with pytest.raises(ValueError, match="two images are named 'IMG_0000.jpg'"):
        reconstruct_views([day1[0], day1[1], day2[0]], K=np.diag([100.0, 100.0, 1.0]))


def test_out_among_the_photos_is_refused(tmp_path, capsys, no_reconstruction):
    """--out as the photos' folder (the next run would read cameras.png as a photo), or
    holding them where a run writes (model-1/): exit 2 before any work, nothing written.
    A folder beside the photos' is fine."""
    photos = tmp_path / "photos"
    _photos(photos, ["a.jpg", "b.jpg"])
    before = sorted(photos.iterdir())
    for out in (photos, tmp_path / "x" / ".." / "photos"):
        assert multiview.main([str(photos), "--out", str(out)]) == 2
        assert capsys.readouterr().err == (f"error: --out '{out}' is the folder of the "
                                           "photos; choose another folder for the outputs\n")
    assert sorted(photos.iterdir()) == before
    nested = _photos(tmp_path / "project" / "model-1", ["c.jpg"])
    assert multiview.main([str(photos / "a.jpg"), str(nested[0]),
                           "--out", str(tmp_path / "project")]) == 2
    assert capsys.readouterr().err == (
        f"error: --out '{tmp_path / 'project'}' holds the photos in '{nested[0].parent}', "
        "where a run writes; choose another folder for the outputs\n")
    assert multiview.main([str(photos), "--out", str(tmp_path), "--no-report"]) == 1
    assert capsys.readouterr().err == "error: reached the reconstruction\n"


def test_a_file_of_the_users_named_like_an_output_is_refused(tmp_path, capsys,
                                                            no_reconstruction):
    """The user's points.ply in --out (no earlier run wrote it): exit 2 before any work;
    an earlier run's own files are no obstacle."""
    photos = _photos(tmp_path / "photos", ["a.jpg", "b.jpg"])
    out = tmp_path / "out"
    out.mkdir()
    (out / "points.ply").write_text("the user's")
    assert multiview.main([*map(str, photos), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"error: --out '{out}' holds '{out / 'points.ply'}', which no earlier scene3D run "
        "there wrote, and the run would replace it; move it or choose another --out\n")
    assert (out / "points.ply").read_text() == "the user's"
    # A further model's file too, before the work (how many models come out is known
    # only at the end).
    (out / "points.ply").unlink()
    (out / "model-1").mkdir()
    (out / "model-1" / "points.ply").write_text("the user's")
    assert multiview.main([*map(str, photos), "--out", str(out)]) == 2
    assert f"holds '{out / 'model-1' / 'points.ply'}', which no earlier" in \
        capsys.readouterr().err
    earlier = tmp_path / "earlier"
    _earlier_run(earlier)
    assert multiview.main([*map(str, photos), "--out", str(earlier)]) == 1
    assert capsys.readouterr().err == "error: reached the reconstruction\n"


def test_ground_truth_for_other_images_is_refused(tmp_path, capsys, no_reconstruction,
                                                 fountain):
    """fountain-P11's camera files (3072x2048) given for photos stored turned (64x96) or
    cropped (120x100): exit 2 before any work, naming both; the photos scaled down pass."""
    photos = [tmp_path / "photos" / name for name in ("a.jpg", "b.jpg")]
    photos[0].parent.mkdir()
    for photo in photos:
        cv2.imwrite(str(photo), np.zeros((96, 64, 3), np.uint8))
    truth = tmp_path / "truth"
    truth.mkdir()
    camera = (fountain / "gt_dense_cameras" / "0004.jpg.camera").read_text()
    for photo in photos:
        (truth / f"{photo.name}.camera").write_text(camera)
    args = [str(tmp_path / "photos"), "--ground-truth", str(truth), "--out",
            str(tmp_path / "out")]
    assert multiview.main(args) == 2
    assert capsys.readouterr().err.startswith(
        f"error: --ground-truth '{truth / 'a.jpg.camera'}' does not describe '{photos[0]}': "
        "images are 64x96 but its camera file is for 3072x2048: the images are turned by 90 "
        "degrees from it (portrait against landscape)")
    for photo in photos:
        cv2.imwrite(str(photo), np.zeros((100, 120, 3), np.uint8))
    assert multiview.main(args) == 2
    assert ("images are 120x100 but its camera file is for 3072x2048, another aspect ratio"
            in capsys.readouterr().err)
    for photo in photos:
        cv2.imwrite(str(photo), np.zeros((64, 96, 3), np.uint8))
    assert multiview.main(args) == 1
    assert capsys.readouterr().err == "error: reached the reconstruction\n"


def test_hidden_files_of_a_folder_are_left_out(tmp_path):
    """macOS's AppleDouble files (._NAME.jpg, not images) and other names starting with
    '.' are not photos of the folder; a hidden file named on its own is still read."""
    folder = tmp_path / "photos"
    photos = _photos(folder, ["0003.jpg", "0004.jpg"])
    (folder / "._0003.jpg").write_bytes(b"\x00\x05\x16\x07" + bytes(100))
    (folder / ".thumb.png").write_bytes(b"")
    assert multiview.image_paths([str(folder)]) == photos
    assert multiview.image_paths([str(folder), str(folder / "._0003.jpg")]) == [
        *photos, folder / "._0003.jpg"]


def test_a_glob_in_a_folder_whose_name_holds_brackets(tmp_path):
    folder = tmp_path / "photos [2024]"
    photos = _photos(folder, ["0003.jpg", "0004.jpg"])
    assert multiview.image_paths([f"{folder}/*.jpg"]) == photos


def test_a_folder_that_does_not_exist_is_named_as_such(tmp_path, capsys):
    """A missing folder (an unset variable in ``$DATA/images``) is not "no image
    matches": said as a folder, with the first missing folder on its way; a missing
    image as an image; a glob in a missing folder names the folder."""
    photos = _photos(tmp_path / "photos", ["0003.jpg", "0004.jpg"])
    cases = {
        str(tmp_path / "photos2"): f"folder not found: '{tmp_path / 'photos2'}'",
        str(tmp_path / "nope" / "images"): (f"folder not found: '{tmp_path / 'nope' / 'images'}'"
                                            f" ('{tmp_path / 'nope'}' does not exist)"),
        str(tmp_path / "photos" / "0009.JPG"): (
            f"image not found: '{tmp_path / 'photos' / '0009.JPG'}'"),
        f"{tmp_path}/nope/*.jpg": (f"no image matches '{tmp_path}/nope/*.jpg': folder not "
                                   f"found: '{tmp_path / 'nope'}'"),
        f"{tmp_path}/photos/*.png": f"no image matches '{tmp_path}/photos/*.png'",
    }
    for spec, message in cases.items():
        with pytest.raises(FileNotFoundError) as info:
            multiview.image_paths([spec, str(photos[0])])
        assert str(info.value) == message
    assert multiview.main([str(tmp_path / "photos2"), str(photos[0]), "--calib", CALIB,
                           "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err == f"error: folder not found: '{tmp_path / 'photos2'}'\n"


def _image_lines(images_txt):
    """The first line of each image in a COLMAP images.txt, split as COLMAP splits it."""
    lines = [line for line in images_txt.splitlines() if not line.startswith("#")]
    return [line.split(" ") for line in lines[::2]]


def test_colmap_names_hold_no_spaces():
    """images.txt separates fields by spaces and cannot quote: each image line has its
    10 fields, the name with '_' for every space."""
    names = ["IMG é 0 (copy).JPG", "plain.jpg", "tab\there.jpg"]
    R = np.stack([np.eye(3)] * 3)
    t = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    files = colmap_text(colmap_model_from_views(
        names, np.diag([500.0, 510.0, 1.0]), (64, 48), np.ones(3, bool), R, t,
        np.zeros((0, 3)), np.zeros((0, 3), np.uint8), np.zeros(0, int), np.zeros(0, int),
        np.zeros((0, 2))))
    fields = _image_lines(files["images.txt"])
    assert [len(f) for f in fields] == [10, 10, 10]
    assert [f[9] for f in fields] == ["IMG_é_0_(copy).JPG", "plain.jpg", "tab_here.jpg"]


def test_photos_with_spaces_in_their_names(fountain, tmp_path, capsys):
    """Three fountain photos named with spaces: the model is written, cameras.json under the
    real names, images.txt with '_' for each space, and one warning line says so."""
    folder = tmp_path / "my photos"
    folder.mkdir()
    names = [f"IMG {i} (copy).jpg" for i in (4, 5, 6)]
    for i, name in zip((4, 5, 6), names):
        (folder / name).symlink_to(fountain / "images" / f"{i:04d}.jpg")
    out = tmp_path / "out"
    assert multiview.main([str(folder), "--calib", CALIB, "--max-width", "400",
                           "--no-plots", "--no-report", "--out", str(out),
                           "--export", "nerfstudio"]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines()
                if line.startswith("WARNING: COLMAP")]
    assert warnings == ["WARNING: COLMAP's text format cannot hold names with spaces: "
                        "colmap/images.txt has 'IMG_4_(copy).jpg' for 'IMG 4 (copy).jpg' "
                        "(and 2 more), '_' for each space, so those names do not match the "
                        "files; rename the photos for tools that open them"]
    assert sorted(json.loads((out / "cameras.json").read_text())) == names
    fields = _image_lines((out / "colmap" / "images.txt").read_text())
    assert all(len(f) == 10 for f in fields)
    assert sorted(f[9] for f in fields) == [n.replace(" ", "_") for n in names]
    # transforms.json, which can hold spaces, names the photos as they are.
    frames = json.loads((out / "transforms.json").read_text())["frames"]
    assert sorted(f["file_path"] for f in frames) == [f"../my photos/{n}" for n in names]
    assert all((out / f["file_path"]).is_file() for f in frames)


def test_an_unknown_export_format_is_a_usage_error(tmp_path, capsys):
    _photos(tmp_path / "photos", ["a.jpg", "b.jpg"])
    with pytest.raises(SystemExit) as info:
        multiview.main([str(tmp_path / "photos"), "--export", "instant-ngp"])
    assert info.value.code == 2
    assert "invalid choice: 'instant-ngp'" in capsys.readouterr().err


def _start_from_the_best_candidate(monkeypatch):
    """The mapper starts from the best-scoring candidate pair, trusted or not, without
    weighing the candidates' focal checks (mapper.initial_pair's ``calibrated``): a run
    under a wrong calibration then reaches the checks after the start on any CPU (which
    candidates a wrong calibration leaves trusted is up to its floating point)."""
    choose, fit = mapper.initial_pair, mapper.reconstruct_from_matches
    monkeypatch.setattr(mapper, "reconstruct_from_matches", lambda *args, **kwargs: (
        dataclasses.replace(fit(*args, **kwargs), trusted=True)))
    monkeypatch.setattr(mapper, "initial_pair",
                        lambda *args, **kwargs: choose(*args, **{**kwargs, "calibrated": False}))


def test_a_calibration_for_another_focal_length_fails_the_check(fountain, tmp_path, capsys,
                                                                monkeypatch):
    """850 px for fountain-P11's 2759 px, all 11 views: six register in one model and
    five in another, with reprojection errors under half a pixel, and both came back
    'ok' with camera centres 33 % of the scene off (a review). Adjusted with the focal
    length free, the observations call for 1.4 and 3.3 times the calibration's: the
    check fails (exit 1), the models are written for inspection with status 'failed',
    and the error says why. (The candidate pairs to start from refute that calibration
    too, which stops the run before any model: the start is chosen here without them,
    to test the model's check.)"""
    _start_from_the_best_candidate(monkeypatch)
    K = read_strecha_camera(fountain / "gt_dense_cameras" / "0004.jpg.camera").K.copy()
    K[0, 0] = K[1, 1] = 850.0
    calib = save_calibration(tmp_path / "wrong.yaml",
                             CameraCalibration(K, np.zeros(5), (3072, 2048)))
    out = tmp_path / "out"
    assert multiview.main([str(fountain / "images"), "--calib", str(calib), "--max-width",
                           "768", "--no-plots", "--no-report", "-q", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: the reconstruction failed its consistency check: ")
    assert len(err.strip().splitlines()) == 1
    # Which of the check's two findings is left after the focal refits depends on the
    # versions and kernels (OpenCV 5.0 with AVX2: only views contradicting their pairs;
    # 5.1: the focal length): a factor when it is quoted, else the views.
    called_for = re.search(r"the views fit a focal length (\d+\.\d+) times the calibration's "
                           r"\(\+-(\d+\.\d+)\)", err)
    if called_for:
        factor, sigma = map(float, called_for.groups())
        assert factor > 1.15 and sigma < 0.1 * (factor - 1)
    else:
        assert re.search(r"the poses of \S+\.jpg(, \S+\.jpg)* contradict their pair geometry",
                         err), err
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["status"] == "failed" and summary["models"][0]["check"]["status"] == "failed"


def test_the_focal_test_keeps_right_calibrations_and_refutes_a_few_percent():
    """The many-view focal test: Strecha models under their right calibrations stay
    within 0.5 % at formal sigmas of 0.0001-0.0003 (up to 24 of them, so the sigma alone
    cannot judge); a calibration 3 % off is measured at least 2.3 % off; a weak model's
    3 % within its own uncertainty refutes nothing."""
    s = SfMSettings()
    assert not refutes_calibration(0.9953, 0.0002, 19, s)
    assert not refutes_calibration(1.0047, 0.00015, 5, s)
    assert refutes_calibration(1.0307, 0.0003, 5, s) and refutes_calibration(0.97, 0.0003, 5, s)
    assert refutes_calibration(1 / 0.88, 0.0003, 19, s)
    assert not refutes_calibration(1.03, 0.01, 19, s)  # 5 sigma is 5 %
    assert not refutes_calibration(1.10, 0.0003, 19, SfMSettings(max_focal_mismatch=0.12))
    # three views: the two-view limits (15 %)
    assert not refutes_calibration(1.059, 0.0006, 3, s) and refutes_calibration(1.4, 0.01, 3, s)


def test_three_views_under_the_right_calibration_are_not_refitted(castle):
    """castle-P19 14-16 at 768 px under the Strecha K: its three views called for 1.059
    times the focal length, then 1.021 times that, and ended with K 8 % long, rotations
    2.2 deg off and a failed check (0.64 deg and ok before the refits; a review). Three
    views are held to the two-view limits."""
    K = read_strecha_camera(castle / "gt_dense_cameras" / "0014.jpg.camera").K
    paths = [castle / "images" / f"{i:04d}.jpg" for i in (14, 15, 16)]
    views = reconstruct_views(paths, K, np.zeros(5), max_width=1000)
    assert views.focal_refits == () and views.ok and views.registered.sum() == 3
    assert views.K[0, 0] == pytest.approx(K[0, 0] / 4)


def test_a_calibration_a_few_percent_off_is_refitted_by_the_views(castle, tmp_path, capsys):
    """castle-P19, all 19 views at 768 px, with a calibration whose focal length is 0.92
    times the truth: the model came back 'ok' with cameras 10.7 deg off (a review). Its
    views call for 1.08 times that focal length, so they are reconstructed again with
    it: the cameras land within a degree of the Strecha ones, K within 1 % of the true
    focal length, and a warning says the calibration was refuted. Without the second
    reconstruction the model fails its check."""
    camera = read_strecha_camera(castle / "gt_dense_cameras" / "0000.jpg.camera")
    wrong = camera.K.copy()
    wrong[:2, :2] *= 0.92
    calib = save_calibration(tmp_path / "wrong.yaml",
                             CameraCalibration(wrong, np.zeros(5), (3072, 2048)))
    out = tmp_path / "out"
    assert multiview.main([str(castle / "images"), "--calib", str(calib), "--ground-truth",
                           str(castle / "gt_dense_cameras"), "--max-width", "768",
                           "--no-plots", "--no-report", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "refuted the calibration's focal length" in err and "lens's distortion?" in err
    summary = json.loads((out / "reconstruction.json").read_text())
    assert summary["status"] == "ok" and summary["registered"] == 19
    assert [w for w in summary["warnings"] if "refuted the calibration's focal" in w]
    assert len(summary["focal_refits"]) >= 1 and summary["focal_refits"][0] > 1.05
    assert summary["K"][0][0] == pytest.approx(camera.K[0, 0] / 4, rel=0.01)
    assert summary["ground_truth"]["max_rotation_error_deg"] < 1.0

    paths = sorted((castle / "images").glob("*.jpg"))
    once = reconstruct_views(paths, wrong, np.zeros(5), max_width=768,
                             settings=SfMSettings(max_focal_refits=0))
    assert once.focal_refits == () and once.main.check.focal_mismatch and not once.ok
    assert once.main.check.focal_scale == pytest.approx(1 / 0.92, rel=0.03)


def test_the_failure_message_names_the_suspect_views_and_the_focal_length_called_for():
    """After two refits the message gives the focal length the views still call for, as a
    multiple of the calibration's (the refits' product times the last model's factor),
    and asks about the lens's distortion as the refit warning does."""
    from types import SimpleNamespace

    check = SimpleNamespace(suspect_views=[2], focal_mismatch=True, focal_scale=1.1,
                            focal_scale_sigma_log=0.002)
    recon = SimpleNamespace(models=[SimpleNamespace(check=check)], focal_refits=(1.1, 1.05),
                            focal_refit_scale=1.1 * 1.05)
    message = multiview._failure_message(recon, ["a.jpg", "b.jpg", "c.jpg"])
    assert "the poses of c.jpg contradict their pair geometry" in message
    assert "a focal length 1.271 times the calibration's" in message
    assert "still after 2 reconstructions" in message and "lens's distortion?" in message
    assert "\n" not in message


def test_the_summary_the_command_writes_is_the_librarys_to_dict(fountain, tmp_path):
    """reconstruction.json is ``MultiViewReconstruction.to_dict()`` with ground truth, but
    for the command's total time and its list of files; read_strecha_cameras reads the
    ground truth the command reads."""
    from scene3D.geometry.camera import adapt_intrinsics_to_size
    from scene3D.io.calibration import load_calibration
    from scene3D.io.datasets import read_strecha_cameras
    from scene3D.io.export import write_json
    from scene3D.io.images import read_image_size

    paths = [fountain / "images" / f"000{i}.jpg" for i in (3, 4, 5)]
    truth_folder = fountain / "gt_dense_cameras"
    out = tmp_path / "out"
    assert multiview.main([*map(str, paths), "--calib", CALIB, "--ground-truth",
                           str(truth_folder), "--max-width", "400", "--no-plots",
                           "--no-report", "--out", str(out), "-q"]) == 0
    written = json.loads((out / "reconstruction.json").read_text())
    camera = load_calibration(CALIB)
    K = adapt_intrinsics_to_size(camera.K, camera.image_size, read_image_size(paths[0]))
    recon = reconstruct_views(paths, K, camera.dist, max_width=400, feature="sift")
    assert recon.ok
    summary = recon.to_dict(ground_truth=read_strecha_cameras(truth_folder, paths))
    write_json(tmp_path / "library.json", summary)
    library = json.loads((tmp_path / "library.json").read_text())
    for entry in (written, library):
        entry.pop("timings_s")
    written.pop("files")
    assert library == written
    assert written["status"] == "ok" and written["ground_truth"]["max_rotation_error_deg"] < 1


def test_dense_writes_what_dense_views_writes_from_the_model(fountain, tmp_path, capsys):
    """``reconstruct-views --dense`` on three fountain photos: dense/ holds the cloud
    dense-views makes from the model written, and a run without --dense takes it away."""
    folder = tmp_path / "photos"
    folder.mkdir()
    for i in (4, 5, 6):
        (folder / f"{i:04d}.jpg").symlink_to(fountain / "images" / f"{i:04d}.jpg")
    out = tmp_path / "out"
    common = [str(folder), "--calib", CALIB, "--max-width", "640", "--no-plots",
              "--no-report", "--out", str(out), "-q"]
    assert multiview.main([*common, "--dense"]) == 0
    summary = json.loads((out / "dense" / "dense.json").read_text())
    assert summary["images"] == str(folder) and len(summary["views"]) == 3
    assert summary["points"] > 10_000
    assert dense_views.main([str(out), "--images", str(folder), "--out",
                             str(tmp_path / "again"), "-q"]) == 0
    again = json.loads((tmp_path / "again" / "dense.json").read_text())
    assert [v["neighbours"] for v in again["views"]] == [v["neighbours"]
                                                          for v in summary["views"]]
    # the same model, read back from its text files: the same cloud to a rounding
    assert abs(again["points"] - summary["points"]) <= 0.01 * summary["points"]
    recorded = json.loads((out / "reconstruction.json").read_text())["files"]
    assert "dense/dense.ply" in recorded and "dense/dense.json" in recorded
    capsys.readouterr()
    assert multiview.main(common) == 0
    assert not (out / "dense" / "dense.ply").exists()
    assert "Removed" in capsys.readouterr().out


@pytest.mark.parametrize("extra, message", [
    (["--mesh"], "--mesh is for --dense"),
    (["--dense"], "--dense needs photos"),
])
def test_dense_options_that_cannot_be_met_are_usage_errors(tmp_path, capsys, extra, message,
                                                         no_reconstruction):
    video = tmp_path / "clip.mp4"
    video.write_bytes(b"")
    assert multiview.main([str(video), "--out", str(tmp_path / "out"), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err, err
    assert not (tmp_path / "out").exists()
