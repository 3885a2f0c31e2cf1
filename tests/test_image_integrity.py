"""Truncated and damaged image files: refused in one line naming the file, before a decoder
prints its own lines on stderr or fills the lost pixels with grey."""

import logging
import re
import subprocess
import sys
import time

import cv2
import numpy as np
import pytest
from PIL import Image

from scene3D.io.image_integrity import intact_image_data
from scene3D.io.images import load_working_image, read_image

from .conftest import REPO


def _photo(width=640, height=480, seed=0):
    """A smooth random texture, BGR uint8 (JPEG-friendly, asymmetric)."""
    noise = np.random.default_rng(seed).random((height // 8 + 1, width // 8 + 1, 3))
    img = cv2.resize(noise.astype(np.float32), (width, height), interpolation=cv2.INTER_CUBIC)
    return (np.clip(img, 0, 1) * 255).astype(np.uint8)


def _encoded(ext, params=()):
    ok, buf = cv2.imencode(ext, _photo(), list(params))
    assert ok
    return buf.tobytes()


def _scan_start(jpeg: bytes) -> int:
    """Where the first scan's compressed data starts (after the SOS segment)."""
    sos = jpeg.index(b"\xff\xda")
    return sos + 2 + int.from_bytes(jpeg[sos + 2:sos + 4], "big")


def _readers(path):
    """Every way a file is decoded: whole, and at a reduced size (libjpeg's scaled IDCT)."""
    return [lambda: read_image(path),
            lambda: load_working_image(path, np.eye(3), np.zeros(5), 300)]


def _garbage(jpeg: bytes) -> bytes:
    """64 random bytes in the middle of the compressed data, one of them an 0xFF that starts
    no valid marker: libjpeg warns 'Corrupt JPEG data: premature end of data segment' and
    decodes the rest of the scan as grey."""
    middle = (_scan_start(jpeg) + len(jpeg)) // 2
    noise = np.random.default_rng(1).integers(0, 255, 64, dtype=np.uint8).tobytes()
    return jpeg[:middle] + noise[:10] + b"\xff\x3f" + noise[12:] + jpeg[middle + 64:]


@pytest.mark.parametrize("name, damage, message", [
    ("garbage.jpg", lambda jpeg: _garbage(jpeg),
     r"a damaged JPEG file \(an invalid marker 0x3f at byte \d+: part of the image would be "
     r"filler or garbage\)"),
    ("half.jpg", lambda jpeg: jpeg[:len(jpeg) // 2],
     r"a truncated JPEG file \(it ends before its end-of-image marker\)"),
    ("header_only.jpg", lambda jpeg: jpeg[:_scan_start(jpeg) + 10],
     r"a truncated JPEG file \(it ends before its end-of-image marker\)"),
])
def test_a_damaged_or_truncated_jpeg_is_refused_naming_it(tmp_path, capfd, name, damage,
                                                          message):
    path = tmp_path / name
    path.write_bytes(damage(_encoded(".jpg")))
    for read in _readers(path):
        with pytest.raises(ValueError, match=rf"^cannot read image '.*{name}': {message}$"):
            read()
    assert capfd.readouterr().err == ""  # no line of libjpeg's


def test_a_jpeg_without_its_end_marker_is_left_to_its_decoder(tmp_path, capfd, fountain):
    """fountain-P11's 0004.jpg without its last two bytes decodes whole in OpenCV (its
    compressed data ends complete): read, not refused. A small photo's does not: refused
    as cut short, in one line."""
    original = (fountain / "images" / "0004.jpg").read_bytes()
    path = tmp_path / "no_eoi.jpg"
    path.write_bytes(original[:-2])
    np.testing.assert_array_equal(read_image(path), read_image(fountain / "images" / "0004.jpg"))
    path.write_bytes(_encoded(".jpg")[:-2])
    with pytest.raises(ValueError, match=r"a truncated JPEG file \(it ends before its "
                                         r"end-of-image marker\)$"):
        read_image(path)
    assert capfd.readouterr().err == ""


def test_restart_markers_out_of_order_are_damage(tmp_path, capfd):
    jpeg = _encoded(".jpg", [cv2.IMWRITE_JPEG_RST_INTERVAL, 4])
    first = jpeg.index(b"\xff\xd0", _scan_start(jpeg))
    path = tmp_path / "restarts.jpg"
    path.write_bytes(jpeg[:first + 1] + b"\xd3" + jpeg[first + 2:])  # RST3 where RST0 goes
    with pytest.raises(ValueError, match="restart markers missing or out of order"):
        read_image(path)
    assert capfd.readouterr().err == ""


def test_stray_bytes_among_the_header_segments_are_dropped_with_a_warning(tmp_path, capfd,
                                                                           caplog):
    """They hold no pixel: the image decodes whole, as the file without them does, and
    libjpeg's 'extraneous bytes' line is not printed."""
    jpeg = _encoded(".jpg")
    sos = jpeg.index(b"\xff\xda")
    path = tmp_path / "stray.jpg"
    path.write_bytes(jpeg[:sos] + b"\x00\x11\x22" + jpeg[sos:])
    with caplog.at_level(logging.WARNING, logger="scene3D.io.image_integrity"):
        img = read_image(path)
    np.testing.assert_array_equal(img, cv2.imdecode(np.frombuffer(jpeg, np.uint8),
                                                    cv2.IMREAD_COLOR))
    assert f"'{path}': 3 stray bytes between the JPEG's header segments" in caplog.text
    assert "Corrupt JPEG data" not in capfd.readouterr().err  # libjpeg's '3 extraneous bytes'


def _tiff_written_by_pillow(tmp_path) -> bytes:
    """Pillow writes the directory first, then the strips (OpenCV the other way round)."""
    Image.fromarray(_photo()[:, :, ::-1]).save(tmp_path / "pil.tif")
    return (tmp_path / "pil.tif").read_bytes()


@pytest.mark.parametrize("name, make, message", [
    ("half.png", lambda tmp: _encoded(".png"), r"a truncated PNG file \(it ends before its "
                                               r"IEND chunk\)"),
    ("half.tif", lambda tmp: _encoded(".tif"), r"a truncated TIFF file \(its directory at byte "
                                               r"\d+ lies past its end\)"),
    ("half_pillow.tif", _tiff_written_by_pillow,
     r"a truncated TIFF file \(its image data runs to byte \d+, past its \d+ bytes\)"),
])
def test_a_truncated_png_or_tiff_is_refused_before_its_decoder_prints(tmp_path, capfd, name,
                                                                      make, message):
    data = make(tmp_path)
    path = tmp_path / name
    path.write_bytes(data[:len(data) // 2])
    for read in _readers(path):
        with pytest.raises(ValueError, match=rf"^cannot read image '.*{name}': {message}$"):
            read()
    assert capfd.readouterr().err == ""  # no 'libpng error', no 'TIFF_Error' lines


@pytest.mark.parametrize("ext, params", [
    (".jpg", []), (".jpg", [cv2.IMWRITE_JPEG_PROGRESSIVE, 1]),
    (".jpg", [cv2.IMWRITE_JPEG_RST_INTERVAL, 4]), (".png", []), (".tif", []), (".webp", []),
])
def test_whole_files_pass_unchanged(ext, params):
    data = np.frombuffer(_encoded(ext, params), np.uint8)
    assert intact_image_data(data, "x") is data


def test_whole_photos_pass_unchanged(fountain, castle, tmp_path):
    """Cameras' JPEGs (the Strecha photos), one with an EXIF block and a trailer after its
    end-of-image marker (as phones append a video or a second picture), pass unchanged."""
    photos = [fountain / "images" / "0004.jpg", castle / "images" / "0004.jpg"]
    exif = Image.Exif()
    exif[0x010F] = "Canon"  # Make
    Image.fromarray(_photo()[:, :, ::-1]).save(tmp_path / "exif.jpg", exif=exif.tobytes())
    (tmp_path / "trailer.jpg").write_bytes((tmp_path / "exif.jpg").read_bytes()
                                           + b"\x00\x00\x00\x18ftypmp42" + bytes(100))
    for path in [*photos, tmp_path / "trailer.jpg"]:
        data = np.fromfile(path, np.uint8)
        assert intact_image_data(data, path) is data


def test_the_check_costs_little_against_decoding(fountain):
    """The marker scan of a 3072x2048 JPEG (3 MB) against its decoding at a quarter size,
    the pipeline's: measured 0.6 ms against 33 ms (2 %); a tenth is allowed for a busy
    machine."""
    data = np.fromfile(fountain / "images" / "0004.jpg", np.uint8)

    def fastest(run, repeats):
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            run()
            times.append(time.perf_counter() - start)
        return min(times)

    check = fastest(lambda: intact_image_data(data, "x"), 20)
    decode = fastest(lambda: cv2.imdecode(data, cv2.IMREAD_REDUCED_COLOR_4), 5)
    assert data.size > 2_000_000 and check < 0.1 * decode


def test_the_command_refuses_a_damaged_photo_in_one_line(tmp_path, capfd):
    """`chapter4.py good.jpg garbage.jpg`: exit code 2 and scene3D's line only, where libjpeg
    printed 'Corrupt JPEG data: ...' and the run went on with grey in the photo."""
    from scene3D.cli.chapter4 import main

    good, bad = tmp_path / "good.jpg", tmp_path / "garbage.jpg"
    good.write_bytes(_encoded(".jpg"))
    bad.write_bytes(_garbage(_encoded(".jpg")))
    assert main([str(good), str(bad), "--out", str(tmp_path / "out"), "--no-plots",
                 "--no-report"]) == 2
    err = capfd.readouterr().err
    assert err.startswith(f"error: cannot read image '{bad}': a damaged JPEG file (an invalid "
                          "marker 0x3f at byte ")
    assert len(err.splitlines()) == 1


@pytest.mark.parametrize("command", ["chapter4", "chapter4 --calib", "reconstruct-views"])
def test_the_commands_refuse_a_truncated_tiff_in_one_line(tmp_path, command):
    """`chapter4.py trunc.tif b.jpg` (a TIFF written by OpenCV, cut in half): exit code 2
    and scene3D's line only, where Pillow warned 'Corrupt EXIF data. Expecting to read 2
    bytes but only got 0.' in two lines of its own while the size was read. A subprocess,
    as a user runs it: pytest would catch the warning in process."""
    from scene3D.io.calibration import CameraCalibration, save_calibration

    data = _encoded(".tif")
    trunc = tmp_path / "trunc.tif"
    trunc.write_bytes(data[:len(data) // 2])
    good = [tmp_path / "a.jpg", tmp_path / "b.jpg"]
    for path, seed in zip(good, (1, 2)):
        cv2.imwrite(str(path), _photo(seed=seed))
    calib = tmp_path / "camera.yaml"
    save_calibration(calib, CameraCalibration(np.array([[500.0, 0, 319.5], [0, 520.0, 239.5],
                                                        [0, 0, 1]]), np.zeros(5), (640, 480)))
    out = ["--out", str(tmp_path / "out")]
    script = {"chapter4": [str(REPO / "chapter4.py"), str(trunc), str(good[1]), *out],
              "chapter4 --calib": [str(REPO / "chapter4.py"), str(trunc), str(good[1]),
                                   "--calib", str(calib), *out],
              "reconstruct-views": ["-m", "scene3D", "reconstruct-views", str(trunc),
                                    *map(str, good), *out]}[command]
    proc = subprocess.run([sys.executable, *script], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2
    assert re.fullmatch(rf"error: cannot read image '{re.escape(str(trunc))}': a truncated "
                        r"TIFF file \(its directory at byte \d+ lies past its end\)\n",
                        proc.stderr), proc.stderr  # one line: no 'Corrupt EXIF data'
