"""Photos of one camera made into photos of several: resized and cropped copies with a
known focal length each, to test what groups photos into cameras and finds each one's
focal length (:mod:`scene3D.multiview.cameras`) against a ground truth."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import cv2

#: Fountain-P11's photos as four cameras: (resize factor, share of the width and height
#: kept about the centre); view ``v`` is taken by camera ``v % 4``.
FOUR_CAMERAS = ((1.0, 1.0), (0.75, 0.9), (0.6, 0.8), (0.5, 0.95))


def write_camera_variants(paths: Sequence[str | os.PathLike], folder: str | os.PathLike,
                          cameras: Sequence[tuple[float, float]] = FOUR_CAMERAS,
                          suffix: str = ".png") -> list[float]:
    """Write photo ``v`` resized by ``cameras[v % C][0]`` and cropped about its centre to
    ``cameras[v % C][1]`` of its width and height (even sizes), as ``folder/NNNN.png``.

    A centred crop keeps the focal length in pixels and the principal point's offset
    from the centre; resizing scales both. So the copy of a photo of focal length ``f``
    has ``f`` times its factor.

    Parameters
    ----------
    paths : sequence of path
        The photos, of one camera.
    folder : path
        Where the copies go (created if needed).
    cameras : sequence of (float, float)
        Each camera's resize factor and kept share.
    suffix : str, default ".png"
        The copies' format.

    Returns
    -------
    list of float
        Each copy's resize factor (its focal length over the photo's).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    factors = []
    for v, path in enumerate(paths):
        scale, keep = cameras[v % len(cameras)]
        img = cv2.imread(os.fspath(path), cv2.IMREAD_COLOR)
        if img is None:
            raise FileNotFoundError(f"cannot read '{path}' as an image")
        if scale != 1:
            img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        h, w = img.shape[:2]
        cw, ch = int(round(w * keep)) // 2 * 2, int(round(h * keep)) // 2 * 2
        x0, y0 = (w - cw) // 2, (h - ch) // 2
        cv2.imwrite(os.fspath(folder / f"{v:04d}{suffix}"), img[y0:y0 + ch, x0:x0 + cw])
        factors.append(float(scale))
    return factors
