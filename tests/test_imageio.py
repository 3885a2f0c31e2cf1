import cv2
import numpy as np
import pytest

from scene3D.imageio import load_bgr, pyr_down_levels, read_image, to_bgr8


def test_conversions_to_bgr8():
    grey = np.full((4, 5), 7, np.uint8)
    assert to_bgr8(grey).shape == (4, 5, 3)
    bgra = np.zeros((4, 5, 4), np.uint8)
    bgra[..., 2] = 200
    out = to_bgr8(bgra)
    assert out.shape == (4, 5, 3) and out[0, 0, 2] == 200
    deep = np.full((4, 5, 3), 65535, np.uint16)
    assert to_bgr8(deep).dtype == np.uint8 and to_bgr8(deep).max() == 255
    with pytest.raises(ValueError, match="uint8 or uint16"):
        to_bgr8(np.zeros((4, 5), np.float32))
    with pytest.raises(ValueError, match="channels"):
        to_bgr8(np.zeros((4, 5, 2), np.uint8))


def test_read_files(tmp_path):
    img = np.random.default_rng(0).integers(0, 255, (20, 30, 4), dtype=np.uint8)
    path = tmp_path / "ä image.png"
    cv2.imwrite(str(tmp_path / "x.png"), img)
    (tmp_path / "x.png").rename(path)
    assert read_image(path).shape == (20, 30, 3)  # alpha dropped
    assert load_bgr(path).shape == (20, 30, 3)
    deep = tmp_path / "deep.png"
    cv2.imwrite(str(deep), np.full((8, 9), 40000, np.uint16))
    assert read_image(deep).dtype == np.uint16 and read_image(deep).ndim == 2
    out = load_bgr(deep)
    assert out.shape == (8, 9, 3) and out.dtype == np.uint8 and out[0, 0, 0] == round(40000 / 257)


def test_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.jpg"):
        read_image(tmp_path / "missing.jpg")
    text = tmp_path / "notes.jpg"
    text.write_text("not an image")
    with pytest.raises(ValueError, match="not an image file"):
        read_image(text)
    empty = tmp_path / "empty.jpg"
    empty.touch()
    with pytest.raises(ValueError, match="empty"):
        read_image(empty)


def test_book_pyramid_rule():
    assert pyr_down_levels(3072) == 2  # 3072 -> 1536 -> 768
    assert pyr_down_levels(1200) == 0
    assert pyr_down_levels(1536, max_width=800) == 1
