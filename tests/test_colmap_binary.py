"""scene3D.io.colmap_binary: COLMAP binary models read and written in scene3D's
conventions, the same model as the text form; round trips through pycolmap's (bench extra)."""

import dataclasses

import numpy as np
import pytest

from scene3D.io.colmap import (
    ColmapCamera,
    ColmapFormatError,
    colmap_model_from_views,
    model_for_photos,
    read_colmap_model,
    read_colmap_text,
    write_colmap_text,
)
from scene3D.io.colmap_binary import read_colmap_binary, write_colmap_binary
from scene3D.io.colmap_model import project_points

from .test_colmap_io import orbit_views, pycolmap_reconstruction

FIELDS = ("image_ids", "names", "camera_ids", "R", "t", "point_ids", "points3d", "colors",
          "errors_px", "obs_view", "obs_point", "obs_xy")


def two_camera_model():
    """The orbit with two cameras: the photos' OPENCV camera with distortion, and a
    PINHOLE one of other intrinsics, taking turns; a name with a space."""
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views()
    names = [f"v {i}.jpg" if i == 3 else f"v{i}.jpg" for i in range(len(R))]
    model = colmap_model_from_views(names, K, size, np.ones(len(R), bool), R, t, X, colors,
                                    obs_view, obs_point, obs_xy)
    model = model_for_photos(model, (1280, 960), [-0.12, 0.03, 4e-4, -6e-4])
    cameras = {1: model.cameras[1],
               5: ColmapCamera.from_opencv(np.array([[900.0, 0, 611.3], [0, 905.0, 488.9],
                                                     [0, 0, 1]]), None, (1280, 960))}
    model = dataclasses.replace(model, cameras=cameras,
                                camera_ids=np.array([1, 5] * (len(R) // 2)))
    xy = model.obs_xy.copy()
    for v in range(len(R)):  # the observations of the second camera's views, its pixels
        mine = model.obs_view == v
        camera = model.camera(v)
        xy[mine] = project_points(model.points3d[model.obs_point[mine]], camera.K,
                                  camera.dist, model.R[v], model.t[v])
    model = dataclasses.replace(model, obs_xy=xy)
    return dataclasses.replace(model, errors_px=model.point_errors_px())


def assert_same_model(a, b):
    assert a.cameras == b.cameras
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_text_and_binary_round_trip_to_the_same_model_exactly(tmp_path):
    model = two_camera_model()
    write_colmap_text(tmp_path / "text", model)
    write_colmap_binary(tmp_path / "binary", model)
    text, binary = read_colmap_text(tmp_path / "text"), read_colmap_binary(tmp_path / "binary")
    # The text form holds names without spaces (COLMAP's format splits at them).
    assert binary.names[3] == "v 3.jpg" and text.names[3] == "v_3.jpg"
    assert_same_model(dataclasses.replace(text, names=model.names), binary)
    # And both are the model written: cameras, points, ids and tracks exactly, the poses
    # to the rounding of the quaternion, the pixels to that of COLMAP's half pixel.
    assert binary.cameras == model.cameras and binary.names == model.names
    for name in ("image_ids", "camera_ids", "point_ids", "points3d", "colors", "errors_px",
                 "obs_view", "obs_point", "t"):
        np.testing.assert_array_equal(getattr(binary, name), getattr(model, name),
                                      err_msg=name)
    np.testing.assert_allclose(binary.R, model.R, rtol=0, atol=1e-15)
    np.testing.assert_allclose(binary.obs_xy, model.obs_xy, rtol=0, atol=1e-12)
    # Written again from what was read, the cameras and points are the same bytes (the
    # rotations differ in the last bit: quaternion to matrix and back).
    write_colmap_binary(tmp_path / "again", binary)
    for name in ("cameras.bin", "points3D.bin"):
        assert (tmp_path / "again" / name).read_bytes() == (tmp_path / "binary" / name
                                                            ).read_bytes(), name


def test_read_colmap_model_takes_either_form(tmp_path):
    model = two_camera_model()
    write_colmap_text(tmp_path / "text", model)
    write_colmap_binary(tmp_path / "binary", model)
    assert read_colmap_model(tmp_path / "binary").names[3] == "v 3.jpg"
    assert read_colmap_model(tmp_path / "text").names[3] == "v_3.jpg"
    # Both there: the binary files, as COLMAP reads them.
    write_colmap_binary(tmp_path / "text", model)
    assert read_colmap_model(tmp_path / "text").names[3] == "v 3.jpg"
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="cameras.txt"):
        read_colmap_model(tmp_path / "empty")
    with pytest.raises(FileNotFoundError, match="folder not found"):
        read_colmap_model(tmp_path / "nothing")


def test_an_unknown_model_and_a_file_cut_short_are_named(tmp_path):
    write_colmap_binary(tmp_path, two_camera_model())
    data = bytearray((tmp_path / "cameras.bin").read_bytes())
    data[12:16] = (5).to_bytes(4, "little")  # the first camera's model: OPENCV_FISHEYE
    (tmp_path / "cameras.bin").write_bytes(bytes(data))
    with pytest.raises(ColmapFormatError, match="OPENCV_FISHEYE") as info:
        read_colmap_binary(tmp_path)
    assert str(tmp_path / "cameras.bin") in str(info.value)

    write_colmap_binary(tmp_path, two_camera_model())
    points = tmp_path / "points3D.bin"
    points.write_bytes(points.read_bytes()[:-5])
    with pytest.raises(ColmapFormatError, match="points3D.bin': the file ends inside point "
                                                "80's track"):
        read_colmap_binary(tmp_path)
    (tmp_path / "images.bin").unlink()
    with pytest.raises(FileNotFoundError, match="images.bin"):
        read_colmap_binary(tmp_path)


def test_pycolmap_reads_our_binary_model_and_we_read_its(tmp_path):
    pycolmap = pytest.importorskip("pycolmap")
    model = two_camera_model()
    write_colmap_binary(tmp_path / "ours", model)
    rec = pycolmap.Reconstruction(str(tmp_path / "ours"))
    assert {i: (c.model.name, c.width, c.height, tuple(c.params))
            for i, c in rec.cameras.items()} == {
        i: (c.model, c.width, c.height, c.params) for i, c in model.cameras.items()}
    for v, image_id in enumerate(model.image_ids):
        image = rec.images[int(image_id)]
        assert image.name == model.names[v] and image.camera_id == model.camera_ids[v]
        pose = image.cam_from_world()
        np.testing.assert_allclose(pose.rotation.matrix(), model.R[v], atol=1e-15)
        np.testing.assert_array_equal(pose.translation, model.t[v])
        # pycolmap projects our points, with our cameras, onto our observations.
        mine = model.obs_view == v
        projected = np.array([rec.cameras[image.camera_id].img_from_cam(
            pose * X) for X in model.points3d[model.obs_point[mine]]]) - 0.5
        np.testing.assert_allclose(projected, model.obs_xy[mine], atol=1e-6)
    for p, point_id in enumerate(model.point_ids):
        np.testing.assert_array_equal(rec.points3D[int(point_id)].xyz, model.points3d[p])
        np.testing.assert_array_equal(rec.points3D[int(point_id)].color, model.colors[p])

    K, size, R, t, X, colors, *_ = orbit_views(n_views=4)
    theirs = pycolmap_reconstruction(pycolmap, K, R, t, X, colors)
    for form in ("binary", "text"):
        (tmp_path / form).mkdir()
    theirs.write_binary(str(tmp_path / "binary"))
    theirs.write_text(str(tmp_path / "text"))
    binary = read_colmap_binary(tmp_path / "binary")
    assert_same_model(read_colmap_text(tmp_path / "text"), binary)
    np.testing.assert_allclose(binary.R, R, atol=1e-9)
    np.testing.assert_allclose(binary.t, t, atol=1e-9)
    np.testing.assert_allclose(binary.camera(1).dist, [-0.1, 0.02, 1e-3, -2e-3])
    np.testing.assert_allclose(binary.reprojection_errors_px(), 0, atol=1e-6)
