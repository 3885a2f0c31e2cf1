"""``scene3d export MODEL --to nerfstudio``: a COLMAP model read from disk (text, binary, or
a reconstruct-views output folder) gives back its true camera-to-world matrices in
transforms.json (read with the test's reader of nerfstudio's documented format); with
--undistort the copies show each point at the pinhole projection transforms.json gives;
bad input is a one-line error (exit code 2) and writes nothing."""

import dataclasses
import json

import cv2
import numpy as np
import pytest

from scene3D.cli import main as scene3d
from scene3D.cli.export import main
from scene3D.io.colmap import colmap_model_from_views, write_colmap_text
from scene3D.io.colmap_binary import write_colmap_binary
from scene3D.io.colmap_model import ColmapCamera
from scene3D.io.export import read_ply

from .test_colmap_io import orbit_views
from .test_nerfstudio import project_nerfstudio, read_transforms
from .test_undistorted import blob_image, distorted_model, points_at_pinhole


def orbit_model():
    """The orbit's model (640x480, fx != fy, off-centre principal point) and its truth."""
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views(n_views=5,
                                                                         n_points=30)
    names = [f"v{i}.jpg" for i in range(len(R))]
    model = colmap_model_from_views(names, K, size, np.ones(len(R), bool), R, t, X, colors,
                                    obs_view, obs_point, obs_xy)
    return model, R, t, X, colors


def write_photos(folder, model, images=None):
    """The model's images as files of their cameras' size (grey, or ``images`` by name)."""
    folder.mkdir(parents=True, exist_ok=True)
    for v, name in enumerate(model.names):
        w, h = model.camera(v).image_size
        image = np.full((h, w, 3), 90, np.uint8) if images is None else images[name]
        assert cv2.imwrite(str(folder / name), image)
    return folder


def files_in(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))


@pytest.mark.parametrize("form", ["text", "binary", "reconstruct-views folder"])
def test_the_export_gives_back_the_true_cameras_in_opengl_axes(tmp_path, form, capsys):
    model, R, t, X, colors = orbit_model()
    photos = write_photos(tmp_path / "photos", model)
    given = tmp_path / "model"
    if form == "binary":
        write_colmap_binary(given, model)
    else:
        write_colmap_text(given / "colmap" if form.startswith("reconstruct") else given, model)
    out = tmp_path / "ns"
    assert scene3d(["export", str(given), "--to", "nerfstudio", "--images", str(photos),
                    "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines == ["5 images, 30 points, 1 camera", f"Wrote '{out / 'transforms.json'}'",
                     f"Wrote '{out / 'sparse_pc.ply'}'"]
    assert files_in(out) == ["sparse_pc.ply", "transforms.json"]
    frames = read_transforms(out / "transforms.json")
    assert [f["image"] for f in frames] == [(photos / n).resolve() for n in model.names]
    for v, frame in enumerate(frames):
        true = np.eye(4)  # right, up, back: OpenCV's x, -y, -z rows of R; the centre
        true[:3, 0], true[:3, 1], true[:3, 2] = R[v][0], -R[v][1], -R[v][2]
        true[:3, 3] = -R[v].T @ t[v]
        np.testing.assert_allclose(frame["c2w"], true, atol=1e-9)
        mine = model.obs_view == v
        np.testing.assert_allclose(project_nerfstudio(X[model.obs_point[mine]], frame) - 0.5,
                                   model.obs_xy[mine], atol=1e-6)
    data = json.loads((out / "transforms.json").read_text())
    assert data["ply_file_path"] == "sparse_pc.ply"
    points, rgb = read_ply(out / "sparse_pc.ply")
    np.testing.assert_allclose(points, X, atol=1e-6)
    np.testing.assert_array_equal(rgb, colors)


def test_undistorted_copies_show_the_points_where_transforms_json_puts_them(tmp_path):
    model = distorted_model()  # 1280x960 photos through a barrel lens
    camera = model.camera(0)
    photos = {}
    for v, name in enumerate(model.names):
        mine = model.obs_view == v
        photos[name] = blob_image(model.obs_xy[mine], camera.image_size)
    folder = write_photos(tmp_path / "photos", model, photos)
    write_colmap_text(tmp_path / "sparse", model)
    assert main([str(tmp_path / "sparse"), "--to", "nerfstudio", "--images", str(folder),
                 "--out", str(tmp_path / "ns"), "--undistort", "-q"]) == 0
    assert files_in(tmp_path / "ns") == ["sparse_pc.ply", "transforms.json", "undistorted",
                                         "undistorted/v0.png", "undistorted/v1.png",
                                         "undistorted/v2.png"]
    data = json.loads((tmp_path / "ns" / "transforms.json").read_text())
    assert all(data[k] == 0 for k in ("k1", "k2", "p1", "p2"))
    moved = []
    for v, frame in enumerate(read_transforms(tmp_path / "ns" / "transforms.json")):
        assert frame["image"] == (tmp_path / "ns" / "undistorted" / f"v{v}.png").resolve()
        image = cv2.imread(str(frame["image"]))
        mine = model.obs_view == v
        _, pinhole = points_at_pinhole(image, model, v, frame)
        moved.append(np.abs(pinhole - model.obs_xy[mine]).max())
    assert min(moved) > 2  # the lens moved them: without undistortion this would fail


def run_error(argv, capsys):
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: "), err
    return err.strip()


def test_bad_input_is_a_one_line_error_and_writes_nothing(tmp_path, capsys):
    model, *_ = orbit_model()
    photos = write_photos(tmp_path / "photos", model)
    write_colmap_text(tmp_path / "sparse", model)
    args = [str(tmp_path / "sparse"), "--to", "nerfstudio", "--images", str(photos)]
    out = ["--out", str(tmp_path / "ns")]
    before = files_in(tmp_path)

    (photos / "v3.jpg").unlink()
    err = run_error([*args, *out], capsys)
    assert "v3.jpg" in err and "no file for the model's image 'v3.jpg'" in err
    cv2.imwrite(str(photos / "v3.jpg"), np.zeros((240, 320, 3), np.uint8))
    assert run_error([*args, *out, "--undistort"], capsys) == (
        "error: image 'v3.jpg' is 320x240, its camera is for 640x480 images")
    assert "cameras.txt" in run_error([str(photos), *args[1:], *out], capsys)
    assert files_in(tmp_path) == before  # no --out folder left behind either

    write_photos(photos, model)
    assert main([*args, *out, "-q"]) == 0
    written = (tmp_path / "ns" / "transforms.json").read_bytes()
    assert run_error([*args, *out], capsys) == (
        f"error: '{tmp_path / 'ns' / 'transforms.json'}' exists (--force replaces it)")
    assert (tmp_path / "ns" / "transforms.json").read_bytes() == written
    assert main([*args, *out, "-q", "--force"]) == 0
    # A wrong --images is named before the files it would replace.
    assert "no file for the model's image 'v0.jpg'" in run_error(
        [*args[:-1], str(tmp_path), *out], capsys)


def test_the_copies_never_replace_the_images_they_come_from(tmp_path, capsys):
    model, *_ = orbit_model()
    model = dataclasses.replace(model, names=tuple(n.replace(".jpg", ".png")
                                                   for n in model.names))
    photos = write_photos(tmp_path / "ns" / "undistorted", model)
    before = {p: p.read_bytes() for p in photos.iterdir()}
    write_colmap_text(tmp_path / "sparse", model)
    err = run_error([str(tmp_path / "sparse"), "--to", "nerfstudio", "--images", str(photos),
                     "--out", str(tmp_path / "ns"), "--undistort", "--force"], capsys)
    assert err == (f"error: the export would write '{photos / 'v0.png'}', one of the images "
                   "it reads; choose another --out")
    assert {p: p.read_bytes() for p in photos.iterdir()} == before


def test_a_rational_lens_needs_undistort(tmp_path, capsys):
    model, *_ = orbit_model()
    camera = model.camera(0)
    rational = ColmapCamera.from_opencv(camera.K, [0, 0, 0, 0, 0, 0.01, 0, 0], camera.image_size)
    model = dataclasses.replace(model, cameras={1: rational})
    photos = write_photos(tmp_path / "photos", model)
    write_colmap_text(tmp_path / "sparse", model)
    args = [str(tmp_path / "sparse"), "--to", "nerfstudio", "--images", str(photos),
            "--out", str(tmp_path / "ns")]
    err = run_error(args, capsys)
    assert "k4..k6" in err and "--undistort writes its images undistorted" in err
    assert not (tmp_path / "ns").exists()
    assert main([*args, "--undistort", "-q"]) == 0
    data = json.loads((tmp_path / "ns" / "transforms.json").read_text())
    assert data["k1"] == 0 and "k3" not in data
