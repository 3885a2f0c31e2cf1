"""scene3d evaluate --no-calib: self-calibrated pairs against the Strecha cameras."""

import csv

import pytest
from PIL import ExifTags, Image

from scene3D.cli.evaluate import main


def test_evaluate_no_calib(fountain, tmp_path, capsys):
    csv_path = tmp_path / "rows.csv"
    assert main([str(fountain), "--no-calib", "--pairs", "3-4", "4-5", "--csv", str(csv_path),
                 "-q"]) == 0
    out = capsys.readouterr().out
    assert "without a calibration: focal length within" in out and "2 prior+refined" in out
    # The focal fit is over the camera files' focal length: no calibration was given.
    assert "the matches' focal length: median" in out and "times the camera files'" in out
    assert "times the calibration's" not in out
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["calibration_source"] for r in rows] == ["prior+refined"] * 2
    for r in rows:  # 768 px, from the 1.2 x prior, 34 % too long
        assert abs(float(r["focal_error"])) < 0.05
        assert float(r["focal_scale"]) == pytest.approx(1 + float(r["focal_error"]))
        assert float(r["rotation_deg"]) < 1.0 and float(r["translation_deg"]) < 2.0


def test_evaluate_no_calib_refuses_a_pair_of_two_cameras(fountain, tmp_path, capsys):
    for sub in ("images", "gt_dense_cameras"):
        (tmp_path / sub).mkdir()
    for name, model in (("0004.jpg", "EOS 5D"), ("0005.jpg", "EOS 6D")):
        exif = Image.Exif()
        exif[ExifTags.Base.Make], exif[ExifTags.Base.Model] = "Canon", model
        with Image.open(fountain / "images" / name) as img:
            img.save(tmp_path / "images" / name, quality=95, exif=exif.tobytes())
        (tmp_path / "gt_dense_cameras" / f"{name}.camera").symlink_to(
            fountain / "gt_dense_cameras" / f"{name}.camera")
    assert main([str(tmp_path), "--no-calib", "-q"]) == 0
    out = capsys.readouterr().out
    assert "| 0004.jpg-0005.jpg | inf | inf | - | - | 0 | 0 | - | no |" in out
    assert "refused: '0005.jpg' was taken with a Canon EOS 6D" in out
    assert "no pair gave a focal length" in out


# -- bad input, refused before any pair is run ---------------------------------------------

def _scene(fountain, folder, broken=None):
    """0003-0005 of fountain-P11 in ``folder`` (images linked), with 0004.jpg's camera file
    lines replaced by ``broken`` (index -> text)."""
    from .test_datasets import camera_text

    for sub in ("images", "gt_dense_cameras"):
        (folder / sub).mkdir(parents=True)
    for name in ("0003.jpg", "0004.jpg", "0005.jpg"):
        (folder / "images" / name).symlink_to(fountain / "images" / name)
        (folder / "gt_dense_cameras" / f"{name}.camera").write_text(
            camera_text(fountain, broken) if broken and name == "0004.jpg" else
            (fountain / "gt_dense_cameras" / f"{name}.camera").read_text())
    return folder


@pytest.fixture
def no_pairs(monkeypatch):
    """Fail the test if any pair is run."""
    import scene3D.cli.evaluate as evaluate

    def refuse(*args, **kwargs):
        pytest.fail("a pair was run before the input was checked")

    monkeypatch.setattr(evaluate, "evaluate_pairs", refuse)


@pytest.mark.parametrize("broken, message", [
    ({8: "inf inf"}, "the image size must be two positive whole numbers, got inf inf"),
    ({8: "nan nan"}, "the image size must be two positive whole numbers, got nan nan"),
    ({4: "1 0 0", 5: "0 1 0", 6: "0 1 0"}, "R is not a rotation"),
    ({5: "nan nan nan"}, "R contains non-finite values"),
    ({0: "0 0 1520.69"}, "K must have positive focal lengths"),
])
def test_evaluate_refuses_an_invalid_camera_file(fountain, tmp_path, capsys, no_pairs,
                                                 broken, message):
    scene = _scene(fountain, tmp_path / "scene", broken)
    assert main([str(scene), "--pairs", "0-1"]) == 2
    err = capsys.readouterr().err
    camera = scene / "gt_dense_cameras" / "0004.jpg.camera"
    assert err == f"error: camera file '{camera}': {err.split(': ', 2)[2]}"
    assert message in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("pairs, message", [
    (["0-1", "0-1"], "pair 0-1 is given twice"),
    (["consecutive", "1-2"], "pair 1-2 is given twice (by 'consecutive' and '1-2')"),
])
def test_evaluate_refuses_a_pair_given_twice(fountain, tmp_path, capsys, no_pairs, pairs,
                                             message):
    assert main([str(_scene(fountain, tmp_path / "scene")), "--pairs", *pairs]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_evaluate_refuses_a_csv_folder_it_cannot_write_before_any_pair(
        fountain, tmp_path, capsys, monkeypatch, no_pairs):
    """A folder that refuses new files (read-only; chmod does not stop root, so every
    file opened in it fails as on a read-only mount)."""
    import errno
    import os

    locked = tmp_path / "rofs"
    locked.mkdir()
    real_open = os.open

    def read_only(path, flags, *args, **kwargs):
        if os.path.dirname(os.path.abspath(path)) == str(locked) and flags & os.O_CREAT:
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", read_only)
    scene = _scene(fountain, tmp_path / "scene")
    assert main([str(scene), "--pairs", "0-1", "--csv", str(locked / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: --csv '{locked / 'x.csv'}' cannot be written")
    assert "Read-only file system" in err and len(err.strip().splitlines()) == 1
    assert list(locked.iterdir()) == []


def test_evaluate_scales_the_camera_files_K_to_photos_stored_smaller(fountain, tmp_path,
                                                                      capsys):
    """The camera file's K holds for its size (3072x2048): photos stored at half that size
    take it halved, and give the pose they give at full size; a crop is refused."""
    import cv2

    for sub in ("images", "gt_dense_cameras"):
        (tmp_path / sub).mkdir()
    for name in ("0004.jpg", "0005.jpg"):
        img = cv2.imread(str(fountain / "images" / name))
        cv2.imwrite(str(tmp_path / "images" / name), cv2.resize(img, (1536, 1024),
                                                                 interpolation=cv2.INTER_AREA))
        camera = fountain / "gt_dense_cameras" / f"{name}.camera"
        (tmp_path / "gt_dense_cameras" / f"{name}.camera").write_text(camera.read_text())
    csv_path = tmp_path / "rows.csv"
    assert main([str(tmp_path), "--pairs", "0-1", "--csv", str(csv_path), "-q"]) == 0
    with open(csv_path, newline="") as f:
        row = next(csv.DictReader(f))
    assert float(row["rotation_deg"]) < 0.1 and float(row["translation_deg"]) < 0.5
    img = cv2.imread(str(tmp_path / "images" / "0005.jpg"))
    cv2.imwrite(str(tmp_path / "images" / "0005.jpg"), img[:, :1400])  # another aspect ratio
    capsys.readouterr()
    for no_calib in ([], ["--no-calib"]):  # no calibration is given: the camera file is named
        assert main([str(tmp_path), "--pairs", "0-1", "-q", *no_calib]) == 2
        err = capsys.readouterr().err.strip()
        assert "0005.jpg': images are 1400x1024 but its camera file is for 3072x2048, another " \
               "aspect ratio" in err
        assert "calibrat" not in err and len(err.splitlines()) == 1
