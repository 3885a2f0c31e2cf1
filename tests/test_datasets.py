"""The fountain-P11 downloader, against a local HTTP server serving the shared copy."""

import functools
import http.server
import logging
import shutil
import threading

import numpy as np
import pytest

from scene3D.errors import DatasetError
from scene3D.io.datasets import FOUNTAIN_P11_SHA256, fetch_fountain_p11, sha256_of, strecha_views

FILES = ("images/K.txt", "gt_dense_cameras/0004.jpg.camera", "images/0004.jpg")


@pytest.fixture
def serve():
    """Start an HTTP server on 127.0.0.1 for a folder; yields (start(folder) -> url, hits)."""
    servers, hits = [], []

    class Handler(http.server.SimpleHTTPRequestHandler):
        def do_GET(self):
            hits.append(self.path)
            super().do_GET()

        def log_message(self, *args):
            pass

    def start(folder):
        handler = functools.partial(Handler, directory=str(folder))
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
        threading.Thread(target=server.serve_forever, daemon=True).start()
        servers.append(server)
        return f"http://127.0.0.1:{server.server_address[1]}/fountain-P11"

    yield start, hits
    for server in servers:
        server.shutdown()
        server.server_close()


def test_download_verifies_and_caches(serve, data_root, tmp_path):
    start, hits = serve
    url = start(data_root)
    empty = tmp_path / "no-data"
    empty.mkdir()
    folder = fetch_fountain_p11(FILES, data_root=empty, cache_dir=tmp_path / "cache",
                                base_url=url)
    assert folder == tmp_path / "cache" / "fountain-P11"
    for name in FILES:
        assert sha256_of(folder / name) == FOUNTAIN_P11_SHA256[name]
    assert len(hits) == 3
    # Second call: everything cached and verified, nothing downloaded.
    fetch_fountain_p11(FILES, data_root=empty, cache_dir=tmp_path / "cache", base_url=url)
    assert len(hits) == 3
    assert not list(folder.rglob("*.part"))


def test_local_copy_is_used_first(data_root, tmp_path):
    folder = fetch_fountain_p11(FILES, data_root=data_root, cache_dir=tmp_path, download=False)
    assert folder == data_root / "fountain-P11"


def test_corrupted_file_is_rejected(serve, data_root, tmp_path):
    start, _ = serve
    mirror = tmp_path / "mirror" / "fountain-P11"
    shutil.copytree(data_root / "fountain-P11" / "gt_dense_cameras", mirror / "gt_dense_cameras")
    (mirror / "images").mkdir()
    (mirror / "images" / "K.txt").write_text("2759.48 0 1520.69\n0 2764.16 1006.81\n0 0 2\n")
    cache = tmp_path / "cache"
    with pytest.raises(DatasetError, match="SHA-256"):
        fetch_fountain_p11(("images/K.txt",), data_root=tmp_path, cache_dir=cache,
                           base_url=start(tmp_path / "mirror"))
    assert not (cache / "fountain-P11" / "images" / "K.txt").exists()
    assert not list(cache.rglob("*.part"))


def test_offline_error_says_what_to_do(tmp_path):
    with pytest.raises(DatasetError, match="SCENE3D_DATA") as info:
        fetch_fountain_p11(("images/K.txt",), data_root=tmp_path, cache_dir=tmp_path,
                           base_url="http://127.0.0.1:9/nothing", timeout_s=2)
    assert "two photos of your own" in str(info.value)


def test_unknown_file_is_refused(tmp_path):
    with pytest.raises(ValueError, match="not a fountain-P11 file"):
        fetch_fountain_p11(("images/9999.jpg",), data_root=tmp_path)


def test_strecha_views_pair_each_image_with_its_camera_file(tmp_path, caplog):
    images, cameras = tmp_path / "images", tmp_path / "gt_dense_cameras"
    images.mkdir()
    cameras.mkdir()
    for name in ("b.jpg", "a.JPG", "c.png", "K.txt"):
        (images / name).write_bytes(b"")
    for name in ("a.JPG", "b.jpg"):  # c.png has no camera file: not a view
        (cameras / f"{name}.camera").write_text("")
    with caplog.at_level(logging.WARNING):
        assert strecha_views(tmp_path) == [(images / "a.JPG", cameras / "a.JPG.camera"),
                                           (images / "b.jpg", cameras / "b.jpg.camera")]
    assert "1 image(s) of" in caplog.text and "left out (the indices count the others): c.png" \
        in caplog.text
    (cameras / "b.jpg.camera").unlink()
    with pytest.raises(ValueError, match="fewer than two images with a .camera file"):
        strecha_views(tmp_path)
    with pytest.raises(FileNotFoundError, match="needs images/ and gt_dense_cameras/"):
        strecha_views(images)
    with pytest.raises(FileNotFoundError, match="scene folder not found"):
        strecha_views(tmp_path / "nope")


def test_a_strecha_scene_holds_each_image_with_its_true_camera(data_root):
    """fountain-P11: the images in name order, their cameras' rotations and centres."""
    from scene3D.io.datasets import read_strecha_camera, read_strecha_scene

    root = data_root / "fountain-P11"
    scene = read_strecha_scene(root)
    assert [p.name for p in scene.paths] == [f"{i:04d}.jpg" for i in range(11)]
    fifth = read_strecha_camera(root / "gt_dense_cameras" / "0004.jpg.camera")
    np.testing.assert_array_equal(scene.R[4], fifth.R)
    np.testing.assert_array_equal(scene.centers[4], fifth.center)
    assert scene.R.shape == (11, 3, 3) and scene.centers.shape == (11, 3)


def camera_text(fountain, lines):
    """0004.jpg's camera file with some of its lines (index -> text) replaced."""
    text = (fountain / "gt_dense_cameras" / "0004.jpg.camera").read_text().splitlines()
    for index, line in lines.items():
        text[index] = line
    return "\n".join(text) + "\n"


# Lines: K 0-2, distortion 3, R (camera-to-world) 4-6, centre 7, size 8.
@pytest.mark.parametrize("lines, message", [
    ({8: "inf inf"}, "the image size must be two positive whole numbers, got inf inf"),
    ({8: "nan nan"}, "the image size must be two positive whole numbers, got nan nan"),
    ({8: "3072 0"}, "the image size must be two positive whole numbers"),
    ({8: "3072.5 2048"}, "the image size must be two positive whole numbers"),
    ({4: "1 0 0", 5: "0 1 0", 6: "0 1 0"}, "R is not a rotation"),
    ({4: "-0.890856 0.0211638 0.453793"}, "R is not a rotation (a reflection"),
    ({5: "nan 0 0"}, "R contains non-finite values"),
    ({0: "-2759.48 0 1520.69"}, "K must have positive focal lengths"),
    ({1: "0 nan 1006.81"}, "K contains non-finite values"),
    ({2: "0 0 2"}, "K must be upper triangular with last row [0, 0, 1]"),
    ({0: "2759.48 0 -50000"}, "K: the principal point (-50000, 1006.81) lies far outside"),
    ({3: "0 inf 0"}, "the distortion must be finite"),
    ({7: "nan -3.81315 0.110559"}, "the camera centre must be finite"),
])
def test_an_invalid_camera_file_is_refused_naming_the_file_and_the_field(fountain, tmp_path,
                                                                          lines, message):
    from scene3D.io.datasets import read_strecha_camera

    path = tmp_path / "0004.jpg.camera"
    path.write_text(camera_text(fountain, lines))
    with pytest.raises(ValueError) as info:
        read_strecha_camera(path)
    assert str(info.value).startswith(f"camera file '{path}': ")
    assert message in str(info.value) and "\n" not in str(info.value)


def test_every_shared_camera_file_is_valid(data_root):
    """The tolerance on R leaves the stored six digits of every Strecha scene through."""
    from scene3D.io.datasets import read_strecha_camera

    files = sorted(data_root.glob("*/gt_dense_cameras/*.camera"))
    assert len(files) >= 11
    for path in files:
        camera = read_strecha_camera(path)
        np.testing.assert_allclose(camera.R @ camera.R.T, np.eye(3), atol=1e-5)
