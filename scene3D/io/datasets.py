"""Datasets: finding, downloading and reading the Strecha fountain-P11 benchmark.

Any scene of the Strecha benchmark in the same layout (``images/NAME`` and
``gt_dense_cameras/NAME.camera``) is listed by :func:`strecha_views`.

Where files are looked for, in order:

1. ``$SCENE3D_DATA/fountain-P11/`` (``SCENE3D_DATA`` defaults to the
   ``shared/data`` folder beside a source checkout, when it exists),
2. the user cache, ``$SCENE3D_CACHE`` or ``$XDG_CACHE_HOME/scene3D`` or
   ``~/.cache/scene3D``,
3. a download from the openMVG/SfM_quality_evaluation GitHub repository (or
   ``$SCENE3D_DATA_URL``) into the cache. Every file is checked against its SHA-256 and written atomically.

Strecha ``.camera`` files hold, line by line: ``K`` (3 rows), the distortion
(one row), ``R`` (3 rows), the camera centre ``C`` (one row) and the image size.
Their ``R`` is camera-to-world (its columns are the camera axes in world
coordinates), so the world-to-camera pose of :mod:`scene3D.geometry` is
``R_wc = R^T``, ``t_wc = -R^T C``.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DatasetError
from ..geometry.camera import (
    adapt_intrinsics_to_size,
    check_intrinsics_for_size,
    validate_intrinsics,
)
from ..geometry.conventions import FloatArray
from ..geometry.conventions import relative_pose as _relative_pose
from .images import IMAGE_SUFFIXES, read_image_size

logger = logging.getLogger(__name__)

FOUNTAIN_P11 = "fountain-P11"
FOUNTAIN_P11_URL = (
    "https://raw.githubusercontent.com/openMVG/SfM_quality_evaluation/master/"
    "Benchmarking_Camera_Calibration_2008/fountain-P11"
)
#: SHA-256 of every file of fountain-P11 (relative path -> hex digest).
FOUNTAIN_P11_SHA256 = {
    "images/0000.jpg": "dba9a66d5f9fa9d8d6a9fe2646b5107c004f5ad5dd99088eab1f27a661415f91",
    "images/0001.jpg": "3fdd650afdd58eb846255e2b3dace394ecc1d9d46a6ed7a9100f5946b8db99b6",
    "images/0002.jpg": "23f39e085c4d6537849bea22e1082343bf81631fddfbebf707433335d0c64741",
    "images/0003.jpg": "e9694c307343c609e6d8e311bdb0e1d010b4d4482c32e2a5e557535d9194b8c8",
    "images/0004.jpg": "e16a6928525bb25b89641d7866f946ab2348a58138c6b5c6074ff1f2285b8297",
    "images/0005.jpg": "4eaf96a4c9bf128946dfb61744d440966ee220be179529a51925b343dfe17f64",
    "images/0006.jpg": "940af32ff053cb480f3038fdc6b2d1bfa3d3a589f1e08cd29bec736e84594a7f",
    "images/0007.jpg": "852317bdf8c1de049bddd5ad2baa035794f425e955a9e9e7f54ad9885d1b684e",
    "images/0008.jpg": "76374ad0a125d5657743463622ab48c892c96d59b353527477c2dc709b129795",
    "images/0009.jpg": "e69d2b5f718a8600020fa98c8f85b0a6bef540a015368509b1df06120a90a693",
    "images/0010.jpg": "d67a19187030bc48875b82be2610c8327fcf93d29713f62e7f744c074d6758dd",
    "images/K.txt": "820441d1ad0051e8b223e4b804c94b1296371fa03267020fd20c0ea5e520589c",
    "gt_dense_cameras/0000.jpg.camera": "ecf7d87adb058729193d1d658181fb91007c309b28222ef14538ea6edf6e3b51",
    "gt_dense_cameras/0001.jpg.camera": "741c418a0a8c5652724761bb6eb18ffec45fd500ebd9ea95b889085195e26fa2",
    "gt_dense_cameras/0002.jpg.camera": "1b4c9a8725f600f587d0a850907797bb5693da0bfaeb01da90bbfb114907c590",
    "gt_dense_cameras/0003.jpg.camera": "882dd2ad95aef47b5d5150f74b7d6adffe7ce9718e8700755e04f1e4c2b4291b",
    "gt_dense_cameras/0004.jpg.camera": "5d91d297976ae000b3c91808c64df90ca9612919839cf63f4b8dd12ef4990c4e",
    "gt_dense_cameras/0005.jpg.camera": "33e3c6a26540b8c42611cd5e4b78dd2f15ef4d1611eb156c888583d04a4045c4",
    "gt_dense_cameras/0006.jpg.camera": "dfa3f23eb4079f2aac81fcf1e313f10f0c5f8afab3c9ee6ef3fa8ead00e0aade",
    "gt_dense_cameras/0007.jpg.camera": "2103aea75d61d7a977b55c36e09bed2af729b7ada2a963e94a37358574b926a2",
    "gt_dense_cameras/0008.jpg.camera": "d1ebbe60304b439d687cb97aad74a306a632ca0605e7052d7a2b52542b295846",
    "gt_dense_cameras/0009.jpg.camera": "b286a42c394537604f99d587b154a2b80f78300b1835c27bd7bbe0d73f691f88",
    "gt_dense_cameras/0010.jpg.camera": "cac077afad3f72f73fb21ea6fbcf639ca6a950a2ea2919f55471326411e2cc0a",
}
#: The book's pair.
BOOK_PAIR = ("images/0004.jpg", "images/0005.jpg")


def default_data_root() -> Path | None:
    """``$SCENE3D_DATA``, else ``shared/data`` beside a source checkout, else None."""
    env = os.environ.get("SCENE3D_DATA")
    if env:
        return Path(env)
    beside_checkout = Path(__file__).resolve().parents[3] / "shared" / "data"
    return beside_checkout if beside_checkout.is_dir() else None


def default_cache_dir() -> Path:
    """The user cache folder for downloaded datasets."""
    env = os.environ.get("SCENE3D_CACHE")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "scene3D"


def sha256_of(path: Path) -> str:
    """Hex SHA-256 of a file.

    Parameters
    ----------
    path : Path
        A file.

    Returns
    -------
    str
    """
    import hashlib  # only when verifying: it costs ~5 ms to import

    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _download(url: str, target: Path, expected_sha256: str, timeout_s: float) -> None:
    """Download ``url`` to ``target`` atomically, refusing content with another hash."""
    import hashlib
    import tempfile
    import urllib.request  # only when downloading: it costs ~20 ms to import

    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".part")
    tmp = Path(tmp_name)
    try:
        digest = hashlib.sha256()
        with os.fdopen(fd, "wb") as out, urllib.request.urlopen(url, timeout=timeout_s) as resp:
            for block in iter(lambda: resp.read(1 << 20), b""):
                digest.update(block)
                out.write(block)
        if digest.hexdigest() != expected_sha256:
            raise DatasetError(
                f"downloaded '{url}' has SHA-256 {digest.hexdigest()[:12]}..., expected "
                f"{expected_sha256[:12]}...: the file is corrupted or has changed upstream"
            )
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


def fetch_fountain_p11(
    files: tuple[str, ...] | None = None,
    *,
    data_root: Path | None = None,
    cache_dir: Path | None = None,
    base_url: str | None = None,
    timeout_s: float = 30.0,
    download: bool = True,
) -> Path:
    """Return a folder holding the requested fountain-P11 files, downloading if needed.

    Parameters
    ----------
    files : tuple of str, optional
        Paths relative to the dataset folder (keys of :data:`FOUNTAIN_P11_SHA256`);
        default all of them.
    data_root, cache_dir : Path, optional
        Override :func:`default_data_root` / :func:`default_cache_dir`.
    base_url : str, optional
        Where ``<base_url>/<file>`` is downloaded from; default ``$SCENE3D_DATA_URL``
        or :data:`FOUNTAIN_P11_URL` (set the variable to use a mirror).
    download : bool
        False: only look locally.

    Returns
    -------
    Path
        The ``fountain-P11`` folder that has every requested file.

    Raises
    ------
    TypeError
        ``files`` is one name (a str or Path) rather than a tuple of them.
    ValueError
        A name is not a fountain-P11 file.
    DatasetError
        A file is missing locally and cannot be downloaded, or its hash is wrong.
    """
    if isinstance(files, (str, bytes, os.PathLike)):
        raise TypeError(f"`files` must be a tuple of file names, got one: "
                        f"'{os.fsdecode(files)}'; write ('{os.fsdecode(files)}',)")
    wanted = tuple(FOUNTAIN_P11_SHA256) if files is None else tuple(files)
    unknown = [f for f in wanted if f not in FOUNTAIN_P11_SHA256]
    if unknown:
        raise ValueError(f"not a fountain-P11 file: {', '.join(unknown)}")
    root = data_root if data_root is not None else default_data_root()
    if root is not None and all((root / FOUNTAIN_P11 / f).is_file() for f in wanted):
        return root / FOUNTAIN_P11
    base_url = base_url or os.environ.get("SCENE3D_DATA_URL") or FOUNTAIN_P11_URL
    cache = (cache_dir if cache_dir is not None else default_cache_dir()) / FOUNTAIN_P11
    for name in wanted:
        target = cache / name
        if target.is_file() and sha256_of(target) == FOUNTAIN_P11_SHA256[name]:
            continue
        if not download:
            raise DatasetError(_missing_message(name, cache, None))
        url = f"{base_url.rstrip('/')}/{name}"
        logger.info("downloading %s", url)
        try:
            _download(url, target, FOUNTAIN_P11_SHA256[name], timeout_s)
        except (OSError, TimeoutError) as exc:  # URLError is an OSError
            raise DatasetError(_missing_message(name, cache, exc)) from exc
    return cache


def _missing_message(name: str, cache: Path, exc: Exception | None) -> str:
    why = f"cannot download it ({getattr(exc, 'reason', exc)})" if exc else "downloads are off"
    return (
        f"fountain-P11 file '{name}' is not available and {why}; set SCENE3D_DATA to a folder "
        f"that holds fountain-P11/, put the files in '{cache}', or use two photos of your "
        "own (a calibration is optional)"
    )


@dataclass(frozen=True)
class StrechaCamera:
    """A ground-truth camera of the Strecha benchmark, as world-to-camera pose.

    Attributes
    ----------
    K : (3, 3) float64
    dist : (5,) float64
        OpenCV distortion ``(k1, k2, 0, 0, k3)`` from the stored radial terms
        (zero for fountain-P11).
    R : (3, 3) float64
        World-to-camera rotation, ``x_cam = R X + t``.
    t : (3,) float64
        World-to-camera translation, ``t = -R C``.
    center : (3,) float64
        Camera centre ``C`` in world coordinates.
    image_size : tuple[int, int]
        (width, height).
    """

    K: FloatArray
    dist: FloatArray
    R: FloatArray
    t: FloatArray
    center: FloatArray
    image_size: tuple[int, int]


def strecha_views(dataset: str | os.PathLike) -> list[tuple[Path, Path]]:
    """The views of a Strecha-format dataset: ``(image, camera file)`` paths, by image name.

    An image counts when ``gt_dense_cameras/`` holds its ``NAME.camera``; the others are
    named in a warning.

    Parameters
    ----------
    dataset : str or os.PathLike
        Folder holding ``images/`` and ``gt_dense_cameras/``.

    Returns
    -------
    list of (Path, Path)


    Raises
    ------
    FileNotFoundError
        ``dataset``, ``images/`` or ``gt_dense_cameras/`` is missing.
    ValueError
        Fewer than two images have a camera file.
    """
    dataset = Path(dataset)
    images, cameras = dataset / "images", dataset / "gt_dense_cameras"
    if not dataset.is_dir():
        raise FileNotFoundError(f"scene folder not found: '{dataset}'")
    if not images.is_dir() or not cameras.is_dir():
        raise FileNotFoundError(f"'{dataset}' needs images/ and gt_dense_cameras/ folders")
    photos = [(p, cameras / f"{p.name}.camera") for p in sorted(images.iterdir())
              if p.suffix.lower() in IMAGE_SUFFIXES]
    views = [(p, camera) for p, camera in photos if camera.is_file()]
    if len(views) < len(photos):  # left out, and the indices count without them
        without = [p.name for p, camera in photos if (p, camera) not in views]
        logger.warning("%d image(s) of '%s' have no camera file and are left out (the "
                       "indices count the others): %s", len(without), dataset,
                       ", ".join(without))
    if len(views) < 2:
        raise ValueError(f"'{dataset}' has fewer than two images with a .camera file")
    return views


@dataclass(frozen=True)
class StrechaScene:
    """The views of a Strecha-format dataset with their true cameras
    (:func:`read_strecha_scene`).

    Attributes
    ----------
    paths : list of Path
        The images, by name.
    cameras : list of StrechaCamera
        Their true cameras, in the same order.
    """

    paths: list[Path]
    cameras: list[StrechaCamera]

    @property
    def R(self) -> FloatArray:
        """World-to-camera rotations ``(V, 3, 3)``."""
        return np.array([c.R for c in self.cameras])

    @property
    def centers(self) -> FloatArray:
        """Camera centres in world coordinates ``(V, 3)``."""
        return np.array([c.center for c in self.cameras])


def read_strecha_scene(dataset: str | os.PathLike) -> StrechaScene:
    """The images of a Strecha-format dataset and their cameras (:func:`strecha_views`,
    :func:`read_strecha_camera`): what a benchmark compares a reconstruction with.

    Parameters
    ----------
    dataset : str or os.PathLike
        Folder holding ``images/`` and ``gt_dense_cameras/``.

    Returns
    -------
    StrechaScene

    Raises
    ------
    FileNotFoundError, ValueError
        As :func:`strecha_views` and :func:`read_strecha_camera`.
    """
    views = strecha_views(dataset)
    return StrechaScene([image for image, _ in views],
                        [read_strecha_camera(camera) for _, camera in views])


#: How far a stored ``R`` may be from orthonormal (``max |R R^T - I|``): the files print
#: six significant digits, which leaves up to about 1e-6 (fountain-P11, castle-P19).
ROTATION_TOLERANCE = 1e-5


def read_strecha_camera(path: str | os.PathLike) -> StrechaCamera:
    """Read a Strecha ``.camera`` file (see the module docstring for the layout).

    Parameters
    ----------
    path : str or os.PathLike
        A ``NAME.camera`` file.

    Returns
    -------
    StrechaCamera


    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        The file does not hold 26 numbers, or one of its fields is not valid: ``K`` not
        a finite camera matrix with positive focal lengths and last row ``0 0 1`` (and its
        principal point within reach of the image), a
        non-finite distortion or centre, ``R`` not a rotation (orthonormal within
        :data:`ROTATION_TOLERANCE`, determinant +1), the size not two positive whole
        numbers. The message names the file and the field.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"camera file not found: '{path}'")
    try:
        values = np.array(path.read_text().split(), dtype=np.float64)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read camera file '{path}': {exc}") from exc
    if values.size != 9 + 3 + 9 + 3 + 2:
        raise ValueError(f"camera file '{path}' must hold 26 numbers, got {values.size}")

    def bad(field: str, why: str) -> ValueError:
        return ValueError(f"camera file '{path}': {field} {why}")

    try:
        K = validate_intrinsics(values[0:9].reshape(3, 3))
    except ValueError as exc:
        raise ValueError(f"camera file '{path}': {str(exc).replace('`K`', 'K')}") from None
    if not np.all(np.isfinite(values[9:12])):
        raise bad("the distortion", f"must be finite, got {_numbers(values[9:12])}")
    k1, k2, k3 = values[9:12]
    dist = np.array([k1, k2, 0.0, 0.0, k3])  # radial terms in OpenCV's order
    R_cam_to_world = values[12:21].reshape(3, 3)
    if not np.all(np.isfinite(R_cam_to_world)):
        raise bad("R", "contains non-finite values")
    off = float(np.abs(R_cam_to_world @ R_cam_to_world.T - np.eye(3)).max())
    if off > ROTATION_TOLERANCE:
        raise bad("R", f"is not a rotation (R R^T differs from the identity by {off:.2g})")
    if np.linalg.det(R_cam_to_world) < 0:
        raise bad("R", "is not a rotation (a reflection: its determinant is -1)")
    center = values[21:24]
    if not np.all(np.isfinite(center)):
        raise bad("the camera centre", f"must be finite, got {_numbers(center)}")
    size = values[24:26]
    if not (np.all(np.isfinite(size)) and np.all(size >= 1) and np.all(size == np.round(size))):
        raise bad("the image size", f"must be two positive whole numbers, got {_numbers(size)}")
    try:
        check_intrinsics_for_size(K, (int(size[0]), int(size[1])))
    except ValueError as exc:
        raise bad("K:", str(exc)) from None
    R = R_cam_to_world.T
    return StrechaCamera(K, dist, R, -R @ center, center, (int(size[0]), int(size[1])))


class CameraFilesError(ValueError):
    """A folder of Strecha camera files does not describe a set of photos.

    Attributes
    ----------
    path : Path
        The folder, or the camera file that does not fit.
    problem : str
        What is wrong, after the path: ``"is not a folder"``, ``"has no camera file for
        'a.jpg' (expected ...)"``, ``"does not describe 'photos/a.jpg': ..."``.
    """

    def __init__(self, path: Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"Strecha camera files: '{path}' {problem}")

    def __reduce__(self) -> tuple:
        return type(self), (self.path, self.problem)


def read_strecha_cameras(folder: str | os.PathLike,
                         photos: list[Path]) -> list[StrechaCamera]:
    """The Strecha camera of every photo, ``folder/NAME.camera``, checked against the photo.

    Parameters
    ----------
    folder : path
        A folder of ``.camera`` files named after the photos (``0000.png.camera``).
    photos : list of Path
        The photos, whose image size the cameras must fit.

    Returns
    -------
    list of StrechaCamera
        One per photo, in their order.

    Raises
    ------
    CameraFilesError
        ``folder`` is not a folder, a photo has no camera file, or a camera is for images
        of another aspect ratio than its photo's (a photo stored turned, a cropped one).
    FileNotFoundError, ValueError
        A camera file that cannot be read (:func:`read_strecha_camera`).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise CameraFilesError(folder, "is not a folder")
    cameras = []
    for photo in photos:
        path = folder / f"{photo.name}.camera"
        if not path.is_file():
            raise CameraFilesError(folder, f"has no camera file for '{photo.name}' "
                                           f"(expected '{path}')")
        camera = read_strecha_camera(path)
        try:
            adapt_intrinsics_to_size(camera.K, camera.image_size, read_image_size(photo),
                                     what="its camera file")
        except ValueError as exc:
            raise CameraFilesError(path, f"does not describe '{photo}': {exc}") from None
        cameras.append(camera)
    return cameras


def _numbers(values: np.ndarray) -> str:
    return " ".join(f"{v:g}" for v in values)


def relative_pose(cam1: StrechaCamera, cam2: StrechaCamera) -> tuple[FloatArray, FloatArray]:
    """``(R, t)`` with ``x_cam2 = R x_cam1 + t`` between two world-to-camera poses.

    Parameters
    ----------
    cam1, cam2 : StrechaCamera
        Ground-truth cameras, world-to-camera ``x_cam = R X + t`` (metres).

    Returns
    -------
    R : (3, 3) float64
        ``R_cam2_from_cam1 = R2 R1^T``.
    t : (3,) float64
        ``t2 - R t1``, in the camera-2 frame; it keeps the metric scale of the ground
        truth (not unit norm: normalise it to compare with a two-view estimate).
    """
    return _relative_pose(cam1.R, cam1.t, cam2.R, cam2.t)
