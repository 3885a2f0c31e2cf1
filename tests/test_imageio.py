import warnings

import cv2
import numpy as np
import pytest

from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.io import images as imageio
from scene3D.io.images import (
    glob_files,
    halve,
    halving_levels,
    header_size,
    iter_working_images,
    load_bgr,
    load_working_image,
    read_image,
    read_image_size,
    to_bgr8,
)


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


def test_16_bit_images_are_scaled_by_the_bits_their_values_use():
    """Full-range 16-bit data by 1/257; 12-bit data in uint16 (at most 4095) by 255/4095,
    not into the bottom 16 levels; 8-bit values in uint16 as they are."""
    ramp = np.arange(0, 4096, 16, dtype=np.uint16).reshape(16, 16)
    twelve = to_bgr8(ramp)[..., 0]
    assert twelve.max() == round(4080 * 255 / 4095) and twelve[0, 1] == round(16 * 255 / 4095)
    full = to_bgr8(np.array([[0, 65535, 40000]], np.uint16))[0, :, 0]
    assert full.tolist() == [0, 255, round(40000 / 257)]
    eight = np.array([[0, 17, 255]], np.uint16)
    assert to_bgr8(eight)[0, :, 0].tolist() == [0, 17, 255]
    # Every value rounded to the nearest level (computed here in float64).
    for bits in (16, 12, 10):
        deep = np.random.default_rng(bits).integers(0, 2**bits, (64, 80, 3), dtype=np.uint16)
        deep[0, 0, 0] = 2**bits - 1
        nearest = np.floor(deep * (255.0 / (2**bits - 1)) + 0.5).astype(np.uint8)
        np.testing.assert_array_equal(to_bgr8(deep), nearest)


def test_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.jpg"):
        read_image(tmp_path / "missing.jpg")
    with pytest.raises(FileNotFoundError, match="a folder, not an image file"):
        read_image(tmp_path)
    # A damaged HEIC photo (its file box and nothing else) is named as such.
    heic = tmp_path / "IMG_0001.HEIC"
    heic.write_bytes(b"\x00\x00\x00\x18ftypheic\x00\x00\x00\x00mif1heic" + bytes(1000))
    with pytest.raises(ValueError, match="cannot read image .*a damaged HEIC/HEIF file"):
        read_image(heic)
    text = tmp_path / "notes.jpg"
    text.write_text("not an image")
    with pytest.raises(ValueError, match="not an image file"):
        read_image(text)
    empty = tmp_path / "empty.jpg"
    empty.touch()
    with pytest.raises(ValueError, match="empty"):
        read_image(empty)
    photo = tmp_path / "photo.jpg"
    cv2.imwrite(str(photo), _textured(1200, 800))
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(photo.read_bytes()[:2000])  # the header survives, the pixels do not
    for max_width in (None, 300):  # full decoding and decoding at the reduced size
        with pytest.raises(ValueError, match="cut.jpg': a truncated JPEG file"):
            load_working_image(cut, np.eye(3), np.zeros(5), max_width)


def test_book_size_rule():
    assert halving_levels(3072) == 2  # 3072 -> 1536 -> 768
    assert halving_levels(1200) == 0
    assert halving_levels(1536, max_width=800) == 1
    assert halving_levels(5000, max_width=None) == 0
    with pytest.raises(ValueError, match="at least 1 px"):
        halving_levels(3072, max_width=0)


def _textured(width, height, seed=0):
    """A smooth random texture (JPEG-friendly), BGR uint8."""
    noise = np.random.default_rng(seed).random((height // 8 + 1, width // 8 + 1, 3))
    img = cv2.resize(noise.astype(np.float32), (width, height), interpolation=cv2.INTER_CUBIC)
    return np.clip(img * 255, 0, 255).astype(np.uint8)


def test_header_sizes_without_decoding(tmp_path, monkeypatch):
    img = _textured(301, 203)
    for ext in (".jpg", ".png", ".bmp", ".tif", ".webp"):
        path = tmp_path / f"x{ext}"
        cv2.imwrite(str(path), img)
        assert read_image_size(path) == (301, 203)
    cv2.imwrite(str(tmp_path / "deep.tif"), np.zeros((203, 301, 3), np.uint16))

    def decoded(path):
        raise AssertionError(f"'{path}' decoded for its size")

    monkeypatch.setattr(imageio, "read_image", decoded)
    for ext in (".jpg", ".png", ".bmp", ".tif", ".webp"):  # Pillow reads TIFF, WebP, BMP
        assert read_image_size(tmp_path / f"x{ext}") == (301, 203)
    assert read_image_size(tmp_path / "deep.tif") == (301, 203)
    # A photo beyond Pillow's decompression-bomb warning (89.5 MP): no warning.
    from PIL import Image

    Image.fromarray(np.zeros((9000, 10000), np.uint8)).save(tmp_path / "large.tif",
                                                            compression="tiff_lzw")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_image_size(tmp_path / "large.tif") == (10000, 9000)
    assert header_size((tmp_path / "x.jpg").read_bytes()[:20]) is None  # header cut off
    assert header_size(b"GIF89a") is None
    # A restart marker (no length field) before the frame header; SOF0 for 200x100.
    assert header_size(b"\xff\xd8\xff\xd0\xff\xc0\x00\x11\x08\x00\x64\x00\xc8\x03") == (200, 100)


def test_a_header_that_lies_falls_back_to_full_decoding(tmp_path, monkeypatch):
    path = tmp_path / "photo.jpg"
    cv2.imwrite(str(path), _textured(1200, 800))
    monkeypatch.setattr(imageio, "header_size", lambda head: (2400, 1600))
    img, native, levels = load_working_image(path, np.eye(3), np.zeros(5), 300)
    assert native == (1200, 800) and levels == 2 and img.shape == (200, 300, 3)


@pytest.mark.parametrize("width, height, levels", [(1200, 800, 2), (1203, 805, 2),
                                                    (2000, 1000, 4)])
def test_jpeg_decoded_small_equals_halving_the_full_image(tmp_path, width, height, levels):
    """The fast path (libjpeg's scaled decoding) and the array path agree in size and pixels."""
    path = tmp_path / "photo.jpg"
    cv2.imwrite(str(path), _textured(width, height), [cv2.IMWRITE_JPEG_QUALITY, 95])
    K, dist = np.eye(3), np.zeros(5)
    max_width = width >> levels
    fast, native, used = load_working_image(path, K, dist, max_width)
    slow, _, _ = load_working_image(read_image(path), K, dist, max_width)
    assert native == (width, height) and used == levels
    assert fast.shape == slow.shape == (height >> levels, width >> levels, 3)
    gray_fast, gray_slow = (cv2.cvtColor(x, cv2.COLOR_BGR2GRAY).astype(np.float32)
                            for x in (fast, slow))
    # The same pixel grid (so the same K): equal up to JPEG noise, while a quarter-pixel
    # shift of the same texture already differs by several grey levels.
    quarter = cv2.warpAffine(gray_slow, np.float32([[1, 0, 0.25], [0, 1, 0]]),
                             gray_slow.shape[::-1], flags=cv2.INTER_CUBIC)
    inner = np.s_[4:-4, 4:-4]
    assert np.abs(gray_fast - gray_slow)[inner].mean() < 1.0
    assert np.abs(quarter - gray_slow)[inner].mean() > 3.0


def test_halving_keeps_pixel_centres_where_K_says():
    """A blob at (x, y) lands where the halved K maps it: x' = (x + 0.5) / 4 - 0.5."""
    K = np.array([[800.0, 0.0, 401.3], [0.0, 800.0, 233.7], [0.0, 0.0, 1.0]])
    x, y = np.meshgrid(np.arange(803), np.arange(602))
    img = 255 * np.exp(-((x - K[0, 2]) ** 2 + (y - K[1, 2]) ** 2) / (2 * 6.0**2))
    small = halve(img.astype(np.float32), 2)
    assert small.shape == (150, 200)
    yy, xx = np.mgrid[:150, :200]
    centroid = np.array([(xx * small).sum(), (yy * small).sum()]) / small.sum()
    np.testing.assert_allclose(centroid, scale_intrinsics_halved(K, 2)[:2, 2], atol=0.02)
    assert scale_intrinsics_halved(K, 2)[0, 0] == 200.0


def test_distorted_jpeg_is_undistorted_at_full_size(tmp_path):
    path = tmp_path / "photo.jpg"
    cv2.imwrite(str(path), _textured(800, 600))
    K = np.array([[700.0, 0, 400], [0, 700.0, 300], [0, 0, 1]])
    dist = np.array([-0.2, 0.05, 0, 0, 0])
    img, _, levels = load_working_image(path, K, dist, 400)
    expected = halve(cv2.undistort(read_image(path), K, dist, None, K), 1)
    assert levels == 1 and np.array_equal(img, expected)


def test_working_images_stream_in_order_and_stop_at_another_size(tmp_path):
    paths = []
    for i, width in enumerate((64, 64, 64, 80, 64)):
        img = np.full((48, width, 3), 40 * i, np.uint8)
        paths.append(tmp_path / f"{i}.png")
        cv2.imwrite(str(paths[-1]), img)
    stream = iter_working_images(paths, np.eye(3), np.zeros(5), max_width=None)
    for i in range(3):
        img, size, levels = next(stream)
        assert img[0, 0, 0] == 40 * i and size == (64, 48) and levels == 0
    with pytest.raises(ValueError, match=r"3.png' is 80x48 but '.*0.png' is 64x48: photos of "
                                         r"one camera at one size are needed; one was cropped"):
        next(stream)


def _png_claiming(width, height):
    """A 67-byte PNG whose IHDR claims ``width x height`` RGB pixels; its IDAT holds two bytes."""
    import struct
    import zlib

    def chunk(kind, body):
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2,
                                                              0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00\x00")) + chunk(b"IEND", b""))


def test_an_image_too_large_for_opencv_is_a_one_line_error(tmp_path, monkeypatch):
    """OpenCV asserts (cv2.error) on a header beyond CV_IO_MAX_IMAGE_PIXELS; that is a ValueError
    naming the file, on every path that decodes: whole, halved, and the size probe."""
    big = tmp_path / "big.png"
    big.write_bytes(_png_claiming(100000, 100000))
    message = (r"cannot read image '.*big.png': too large for OpenCV \(its header says "
               r"100000x100000 pixels\), or a damaged file")
    with pytest.raises(ValueError, match=message):
        read_image(big)
    for max_width in (None, 768):
        with pytest.raises(ValueError, match=message):
            load_working_image(big, np.eye(3), np.zeros(5), max_width)
    bmp = tmp_path / "big.bmp"  # no size header read: the size probe decodes it
    bmp.write_bytes(b"BM" + (70).to_bytes(4, "little") + bytes(4) + (54).to_bytes(4, "little")
                    + (40).to_bytes(4, "little") + (100000).to_bytes(4, "little") * 2
                    + (1).to_bytes(2, "little") + (24).to_bytes(2, "little") + bytes(40))
    with pytest.raises(ValueError, match=r"cannot read image '.*big.bmp': too large for OpenCV"):
        read_image_size(bmp)
    # Any other assertion of a decoder, here in libjpeg's reduced-size path, says damaged.
    photo = tmp_path / "photo.jpg"
    cv2.imwrite(str(photo), _textured(1200, 800))

    def asserting(data, flags):
        raise cv2.error("OpenCV(5.0.0) loadsave.cpp: error: (-215:Assertion failed) in imdecode_")

    monkeypatch.setattr(imageio.cv2, "imdecode", asserting)
    with pytest.raises(ValueError, match=r"'.*photo.jpg': a damaged image file \(its header "
                                         r"says 1200x800 pixels\)$"):
        load_working_image(photo, np.eye(3), np.zeros(5), 300)


@pytest.mark.parametrize("height", [1, 3])
@pytest.mark.parametrize("ext", [".jpg", ".png"])
def test_a_strip_too_thin_to_halve_is_named_before_decoding(tmp_path, ext, height):
    """3072 px wide, 1 or 3 high, at --max-width 768: libjpeg's reduced decoding would give
    an empty image; JPEG and PNG are refused alike, naming the file."""
    path = tmp_path / f"pano{ext}"
    cv2.imwrite(str(path), _textured(3072, height))
    with pytest.raises(ValueError, match=rf"'.*pano{ext}': a 3072x{height} image cannot be "
                                         rf"halved 2 times \(to 768x0 pixels\)"):
        load_working_image(path, np.eye(3), np.zeros(5), 768)
    thin = tmp_path / f"thin{ext}"  # halved once, three rows still leave one
    cv2.imwrite(str(thin), _textured(3072, 3))
    img, native, levels = load_working_image(thin, np.eye(3), np.zeros(5), 1536)
    assert native == (3072, 3) and levels == 1 and img.shape == (1, 1536, 3)


def test_a_jpeg_header_claiming_more_pixels_than_the_file_holds_is_damaged(tmp_path):
    """A 1200x800 JPEG whose frame header was patched to 65000x65000: libjpeg would make a
    grey 8125x8125 image of it at 1/8 size (no keypoints); it is refused as damaged, without
    decoding, by the size probe and the readers alike."""
    photo = tmp_path / "photo.jpg"
    cv2.imwrite(str(photo), _textured(1200, 800))
    data = bytearray(photo.read_bytes())
    sof = data.index(b"\xff\xc0")
    data[sof + 5:sof + 9] = (65000).to_bytes(2, "big") * 2
    patched = tmp_path / "patched.jpg"
    patched.write_bytes(bytes(data))
    message = (r"cannot read image '.*patched.jpg': a damaged JPEG file \(its header says "
               r"65000x65000 pixels, more than its \d+ bytes can hold\)")
    with pytest.raises(ValueError, match=message):
        read_image_size(patched)
    with pytest.raises(ValueError, match=message):
        read_image(patched)
    for max_width in (None, 768):
        with pytest.raises(ValueError, match=message):
            load_working_image(patched, np.eye(3), np.zeros(5), max_width)
    # Complete files of one flat colour, the smallest JPEGs there are, are not refused.
    for progressive, shape in [(0, (4000, 4000)), (1, (4000, 4000, 3))]:
        flat = tmp_path / f"flat{progressive}.jpg"
        cv2.imwrite(str(flat), np.full(shape, 77, np.uint8),
                    [cv2.IMWRITE_JPEG_PROGRESSIVE, progressive, cv2.IMWRITE_JPEG_OPTIMIZE, 1,
                     cv2.IMWRITE_JPEG_QUALITY, 10])
        assert read_image_size(flat) == (4000, 4000)
        assert load_working_image(flat, np.eye(3), np.zeros(5), 1000)[0].shape == (1000, 1000, 3)


def test_a_glob_finds_photos_in_a_folder_whose_name_holds_brackets(tmp_path):
    """'photos [2024]/*.jpg': a glob reads the brackets as a set of characters and finds
    nothing; the folder as written exists, so it is taken literally. A set of characters
    in a folder that does not exist as written still works as one."""
    folder = tmp_path / "photos [2024]"
    folder.mkdir()
    for name in ("b.jpg", "a.jpg", "notes.txt"):
        (folder / name).write_bytes(b"")
    assert glob_files(f"{folder}/*.jpg") == [folder / "a.jpg", folder / "b.jpg"]
    (tmp_path / "set1").mkdir()
    (tmp_path / "set1" / "c.jpg").write_bytes(b"")
    assert glob_files(f"{tmp_path}/set[0-9]/*.jpg") == [tmp_path / "set1" / "c.jpg"]
    assert glob_files(f"{folder}/*.png") == []


def test_files_folders_and_globs_name_images_in_the_order_given(tmp_path):
    """scene3D.io.paths: a folder's images (sorted, hidden ones left out), a glob's files, a
    file itself; a spec that names nothing says which folder is missing; lists_file and
    utf8_name_problem answer for a path that need not exist."""
    from scene3D.io.paths import image_files, lists_file, utf8_name_problem

    folder = tmp_path / "photos"
    folder.mkdir()
    for name in ("b.jpg", "a.jpg", "._a.jpg", "notes.txt"):
        (folder / name).write_bytes(b"")
    single = tmp_path / "c.png"
    single.write_bytes(b"")
    assert image_files([str(single), str(folder), f"{folder}/b*"]) == [
        single, folder / "a.jpg", folder / "b.jpg", folder / "b.jpg"]
    with pytest.raises(FileNotFoundError, match=r"^folder not found: '.*/gone/images' "
                                                r"\('.*/gone' does not exist\)$"):
        image_files([str(tmp_path / "gone" / "images")])
    with pytest.raises(FileNotFoundError, match=r"^no image matches '.*/photos/\*\.png'$"):
        image_files([f"{folder}/*.png"])
    assert lists_file(str(folder), folder / "new.png") and not lists_file(str(folder),
                                                                           folder / "new.txt")
    assert utf8_name_problem(folder) == ""
