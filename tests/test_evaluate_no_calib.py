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
