"""scene3D.io.nerfstudio: transforms.json for NeRF and splatting trainers, checked with a
small reader written from nerfstudio's documentation of the format
(https://docs.nerf.studio/quickstart/data_conventions.html)."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from scene3D.io.colmap import (
    ColmapCamera,
    colmap_model_from_views,
    model_for_photos,
    read_colmap_text,
    write_colmap_text,
)
from scene3D.io.nerfstudio import camera_to_world_opengl, write_nerfstudio

from .test_colmap_io import orbit_views


def read_transforms(path: Path) -> list[dict]:
    """nerfstudio's format as its documentation describes it: intrinsics at the top or in
    each frame (a frame's own win), ``transform_matrix`` camera-to-world with the camera
    looking along -z, y up; pixel centres at +0.5; ``file_path`` relative to the file.
    Returns per frame the image path, the intrinsics and the 4x4 matrix."""
    data = json.loads(path.read_text())
    keys = ("camera_model", "fl_x", "fl_y", "cx", "cy", "w", "h", "k1", "k2", "k3", "p1", "p2")
    frames = []
    for frame in data["frames"]:
        intrinsics = {k: frame.get(k, data.get(k)) for k in keys}
        assert intrinsics["camera_model"] in ("OPENCV", "OPENCV_FISHEYE")
        frames.append({"image": (path.parent / frame["file_path"]).resolve(),
                       "intrinsics": intrinsics,
                       "c2w": np.array(frame["transform_matrix"], dtype=float)})
    return frames


def project_nerfstudio(X: np.ndarray, frame: dict) -> np.ndarray:
    """Pixels (pixel centres at +0.5) of world points in a frame, without distortion."""
    c2w, k = frame["c2w"], frame["intrinsics"]
    w2c = np.linalg.inv(c2w)
    cam = X @ w2c[:3, :3].T + w2c[:3, 3]
    depth = -cam[:, 2]  # in front is -z
    assert np.all(depth > 0)
    return np.column_stack([k["cx"] + k["fl_x"] * cam[:, 0] / depth,
                            k["cy"] - k["fl_y"] * cam[:, 1] / depth])  # y up, rows down


def test_the_true_cameras_come_back_in_opengl_axes(tmp_path):
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views()
    names = [f"v{i}.png" for i in range(len(R))]
    model = colmap_model_from_views(names, K, size, np.ones(len(R), bool), R, t, X, colors,
                                    obs_view, obs_point, obs_xy)
    photos = tmp_path / "photos"
    out = tmp_path / "export" / "transforms.json"
    out.parent.mkdir()
    write_nerfstudio(out, model, photos, ply_file=tmp_path / "export" / "points.ply")
    data = json.loads(out.read_text())
    assert data["ply_file_path"] == "points.ply"
    assert (data["w"], data["h"]) == size and "fl_x" not in data["frames"][0]
    frames = read_transforms(out)
    assert [f["image"] for f in frames] == [(photos / n).resolve() for n in names]
    assert data["frames"][0]["file_path"] == "../photos/v0.png"
    for v, frame in enumerate(frames):
        C = -R[v].T @ t[v]
        # The camera's right, up and back axes in the world: OpenCV's x, -y, -z rows of R.
        true = np.eye(4)
        true[:3, 0], true[:3, 1], true[:3, 2], true[:3, 3] = R[v][0], -R[v][1], -R[v][2], C
        np.testing.assert_allclose(frame["c2w"], true, atol=1e-6)
        # The intrinsics put the points where the camera saw them (OpenCV + 0.5).
        mine = obs_view == v
        np.testing.assert_allclose(project_nerfstudio(X[obs_point[mine]], frame) - 0.5,
                                   obs_xy[mine], atol=1e-6)
        assert frame["intrinsics"]["k1"] == 0 and frame["intrinsics"]["p2"] == 0


def test_a_colmap_model_read_back_exports_the_same_cameras(tmp_path):
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views()
    names = [f"v{i}.png" for i in range(len(R))]
    model = colmap_model_from_views(names, K, size, np.ones(len(R), bool), R, t, X, colors,
                                    obs_view, obs_point, obs_xy)
    write_colmap_text(tmp_path / "sparse", model)
    write_nerfstudio(tmp_path / "transforms.json", read_colmap_text(tmp_path / "sparse"),
                     tmp_path / "images")
    frames = read_transforms(tmp_path / "transforms.json")
    assert [f["image"].name for f in frames] == names
    for v, frame in enumerate(frames):
        np.testing.assert_allclose(frame["c2w"][:3, 3], -R[v].T @ t[v], atol=1e-9)
        np.testing.assert_allclose(frame["c2w"][:3, :3] @ np.diag([1, -1, -1]), R[v].T,
                                   atol=1e-9)
        mine = obs_view == v
        np.testing.assert_allclose(project_nerfstudio(X[obs_point[mine]], frame) - 0.5,
                                   obs_xy[mine], atol=1e-6)


def test_several_cameras_give_intrinsics_per_frame_with_their_distortion(tmp_path):
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views(n_views=4)
    names = [f"v{i}.png" for i in range(len(R))]
    model = colmap_model_from_views(names, K, size, np.ones(len(R), bool), R, t, X, colors,
                                    obs_view, obs_point, obs_xy)
    model = model_for_photos(model, (1280, 960), [-0.1, 0.02, 1e-3, -2e-3])
    second = ColmapCamera.from_opencv(2 * K, None, (1280, 960))
    cameras = {1: model.cameras[1], 2: second}
    model = dataclasses.replace(model, cameras=cameras,
                                camera_ids=np.array([1, 2, 1, 2]))
    out = tmp_path / "transforms.json"
    write_nerfstudio(out, model, {n: tmp_path / "img" / n for n in names})
    data = json.loads(out.read_text())
    assert "fl_x" not in data
    frames = read_transforms(out)
    first, other = frames[0]["intrinsics"], frames[1]["intrinsics"]
    assert (first["w"], first["h"]) == (1280, 960)
    assert (first["k1"], first["k2"], first["p1"], first["p2"]) == (-0.1, 0.02, 1e-3, -2e-3)
    assert other["fl_x"] == pytest.approx(2 * K[0, 0]) and other["k1"] == 0
    assert first["cx"] == pytest.approx(2 * (K[0, 2] + 0.5))
    np.testing.assert_allclose(frames[3]["c2w"], camera_to_world_opengl(R[3], t[3]))


def test_a_model_without_an_image_path_is_refused(tmp_path):
    K, size, R, t, X, colors, obs_view, obs_point, obs_xy = orbit_views(n_views=3)
    model = colmap_model_from_views(["a", "b", "c"], K, size, np.ones(3, bool), R, t, X,
                                    colors, obs_view, obs_point, obs_xy)
    with pytest.raises(ValueError, match="no path for the model's image 'c'"):
        write_nerfstudio(tmp_path / "transforms.json", model, {"a": "a", "b": "b"})
    assert not (tmp_path / "transforms.json").exists()
