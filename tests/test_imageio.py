"""arenabench.imageio: conversions to BGR uint8 and one-line errors for bad files."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from arenabench.imageio import ImageLoadError, decode_image, load_image

EXAMPLE = Path(__file__).parent / "data" / "task1c_image.jpg"


def test_loads_the_example_as_bgr_uint8():
    img = load_image(EXAMPLE)
    assert img.shape == (1000, 1000, 3) and img.dtype == np.uint8
    np.testing.assert_array_equal(img, cv2.imread(str(EXAMPLE)))


def test_grayscale_png_becomes_bgr(tmp_path):
    gray = np.arange(256, dtype=np.uint8).reshape(16, 16)
    cv2.imwrite(str(tmp_path / "g.png"), gray)
    img = load_image(tmp_path / "g.png")
    assert img.shape == (16, 16, 3)
    np.testing.assert_array_equal(img[:, :, 1], gray)


def test_rgba_png_drops_alpha(tmp_path):
    bgra = np.zeros((20, 20, 4), np.uint8)
    bgra[..., 0], bgra[..., 1], bgra[..., 2], bgra[..., 3] = 10, 20, 30, 0
    cv2.imwrite(str(tmp_path / "a.png"), bgra)
    img = load_image(tmp_path / "a.png")
    assert img.shape == (20, 20, 3)
    assert img[0, 0].tolist() == [10, 20, 30]


def test_16bit_png_is_scaled_to_8bit(tmp_path):
    img16 = np.full((10, 12, 3), 65535, np.uint16)
    img16[0, 0] = (0, 257 * 100, 257 * 200)
    cv2.imwrite(str(tmp_path / "d.png"), img16)
    img = load_image(tmp_path / "d.png")
    assert img.dtype == np.uint8 and img.shape == (10, 12, 3)
    assert img[0, 0].tolist() == [0, 100, 200] and img[5, 5].tolist() == [255, 255, 255]


def test_16bit_single_channel(tmp_path):
    cv2.imwrite(str(tmp_path / "g16.png"), np.full((8, 8), 257 * 42, np.uint16))
    img = load_image(tmp_path / "g16.png")
    assert img.shape == (8, 8, 3) and int(img[0, 0, 0]) == 42


def _write(path, data):
    path.write_bytes(data)
    return path


def _truncated(tmp_path, name, fraction):
    data = EXAMPLE.read_bytes() if name.endswith(".jpg") else cv2.imencode(
        ".png", cv2.imread(str(EXAMPLE)))[1].tobytes()
    path = tmp_path / name
    path.write_bytes(data[: int(len(data) * fraction)])
    return path


@pytest.mark.parametrize(
    "make, fragment",
    [
        (lambda d: d / "missing.png", "no such file"),
        (lambda d: d, "is a directory"),
        (lambda d: _write(d / "empty.png", b""), "empty file"),
        (lambda d: _write(d / "t.png", b"not an image\n"), "not a decodable image"),
        (lambda d: _truncated(d, "cut.jpg", 0.6), "truncated JPEG"),
        (lambda d: _truncated(d, "cut.png", 0.6), "truncated PNG"),
        (lambda d: _truncated(d, "cut2.png", 0.999), "truncated PNG"),
    ],
)
def test_bad_files_raise_one_line_naming_the_file(tmp_path, make, fragment):
    path = make(tmp_path)
    with pytest.raises(ImageLoadError, match=fragment) as info:
        load_image(path)
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg
    assert isinstance(info.value, ValueError)


def test_decode_image_from_bytes():
    img = decode_image(EXAMPLE.read_bytes(), name="example")
    assert img.shape == (1000, 1000, 3)
    with pytest.raises(ImageLoadError, match=r"^blob: "):
        decode_image(b"\x89PNG\r\n\x1a\nrubbish", name="blob")


def test_encode_png_is_lossless_and_the_writers_one_encoder():
    from arenabench.imageio import encode_png

    rng = np.random.default_rng(0)
    bgr = rng.integers(0, 256, (37, 53, 3), dtype=np.uint8)
    png = encode_png(bgr)
    assert png.startswith(b"\x89PNG")
    assert np.array_equal(decode_image(png), bgr)
    assert encode_png(bgr) == png


def test_jpeg_layout_and_quality_of_the_example_and_of_other_encodings():
    """The example's tables and 4:2:0 sampling are cv2.imwrite's at quality 95; another
    quality or 4:4:4 is told apart; a PNG is refused with a one-line error."""
    from arenabench.imageio import (
        encode_image,
        encode_jpeg,
        jpeg_layout,
        jpeg_quality,
        jpeg_settings,
    )

    example = EXAMPLE.read_bytes()
    assert jpeg_quality(example) == 95
    assert jpeg_layout(example).sampling == ((2, 2), (1, 1), (1, 1))
    assert jpeg_settings(example) == (95, "420")
    bgr = np.zeros((16, 16, 3), np.uint8)
    assert jpeg_quality(encode_jpeg(bgr, quality=80)) == 80
    assert encode_image(bgr, image_format="jpeg", jpeg_quality=95) == encode_jpeg(bgr, quality=95)
    ok, full = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 95,
                                          cv2.IMWRITE_JPEG_SAMPLING_FACTOR,
                                          cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444])
    assert ok and jpeg_layout(full.tobytes()).sampling == ((1, 1), (1, 1), (1, 1))
    assert jpeg_settings(full.tobytes()) == (95, "444")
    assert full.tobytes() == encode_jpeg(bgr, quality=95, subsampling="444")
    with pytest.raises(ImageLoadError, match="not a JPEG"):
        jpeg_layout(encode_image(bgr, image_format="png", jpeg_quality=95))
    with pytest.raises(ValueError, match="quality"):
        encode_jpeg(bgr, quality=0)
    with pytest.raises(ValueError, match="unknown image format"):
        encode_image(bgr, image_format="webp", jpeg_quality=95)


def test_jpeg_settings_read_back_every_quality_and_subsampling_written():
    """Every quality 1..100 and every subsampling encode_jpeg writes is read back exactly from
    the file's own tables and frame header (libjpeg's scaling of the standard tables); 4:2:0
    is written without the option, byte for byte as cv2.imwrite's default."""
    from arenabench.imageio import (
        JPEG_SUBSAMPLINGS,
        encode_jpeg,
        jpeg_quality,
        jpeg_settings,
    )

    rng = np.random.default_rng(1)
    bgr = rng.integers(0, 256, (24, 40, 3), dtype=np.uint8)
    default = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()
    assert encode_jpeg(bgr, quality=90) == default
    for subsampling in JPEG_SUBSAMPLINGS:
        for quality in range(1, 101):
            data = encode_jpeg(bgr, quality=quality, subsampling=subsampling)
            assert jpeg_settings(data) == (quality, subsampling), (quality, subsampling)
            assert jpeg_quality(data) == quality
    grey = cv2.imencode(".jpg", bgr[:, :, 0], [cv2.IMWRITE_JPEG_QUALITY, 70])[1].tobytes()
    assert jpeg_settings(grey) == (70, "gray")


def test_jpeg_settings_estimate_the_quality_of_tables_of_their_own():
    """A file whose luminance table is no libjpeg-scaled one (here: quality 80's table with
    a few entries moved, as another encoder might write) gets the nearest quality, and
    jpeg_quality says there is no exact one."""
    from arenabench.imageio import encode_jpeg, jpeg_layout, jpeg_quality, jpeg_settings

    data = bytearray(encode_jpeg(np.zeros((16, 16, 3), np.uint8), quality=80))
    start = data.index(b"\xff\xdb") + 5  # first DQT's first table (id 0), zig-zag order
    table = list(jpeg_layout(bytes(data)).tables[0])
    assert list(data[start:start + 64]) == table
    for k in (3, 17, 40):
        data[start + k] += 1
    assert jpeg_quality(bytes(data)) is None
    assert jpeg_settings(bytes(data)) == (80, "420")


def test_a_subsampling_opencv_cannot_write_is_refused_in_one_line(monkeypatch):
    """Without IMWRITE_JPEG_SAMPLING_FACTOR (OpenCV < 4.7) only 4:2:0 can be written: asking
    for another is one line naming the OpenCV version, not a silent 4:2:0."""
    from arenabench import imageio

    bgr = np.zeros((16, 16, 3), np.uint8)
    with pytest.raises(ValueError, match=r"unknown JPEG subsampling '411' \(one of 420, 422"):
        imageio.encode_jpeg(bgr, quality=90, subsampling="411")
    monkeypatch.delattr(cv2, "IMWRITE_JPEG_SAMPLING_FACTOR")
    assert imageio.jpeg_subsampling_problem("420") is None
    assert imageio.encode_jpeg(bgr, quality=90).startswith(b"\xff\xd8")
    with pytest.raises(ValueError, match=r"needs OpenCV >= 4\.7") as err:
        imageio.encode_jpeg(bgr, quality=90, subsampling="444")
    assert "\n" not in str(err.value)
