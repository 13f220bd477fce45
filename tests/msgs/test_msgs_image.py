"""numpy <-> sensor_msgs/Image without cv_bridge: encodings, row padding, bad headers."""

from __future__ import annotations

import numpy as np
import pytest

from go2vlm.msgs.image import image_to_numpy, numpy_to_image, to_bgr
from go2vlm.msgs.sensor_msgs import Image
from go2vlm.msgs.std_msgs import Header

ENCODINGS = [
    ("bgr8", 3, np.uint8),
    ("rgb8", 3, np.uint8),
    ("mono8", 1, np.uint8),
    ("bgra8", 4, np.uint8),
    ("rgba8", 4, np.uint8),
    ("mono16", 1, np.uint16),
]


def sample(h: int, w: int, channels: int, dtype: type) -> np.ndarray:
    rng = np.random.default_rng(h * 1000 + w * 10 + channels)
    shape = (h, w) if channels == 1 else (h, w, channels)
    return rng.integers(0, np.iinfo(dtype).max, size=shape, endpoint=True, dtype=dtype)


@pytest.mark.parametrize(("encoding", "channels", "dtype"), ENCODINGS)
@pytest.mark.parametrize(("h", "w"), [(1, 1), (3, 5), (48, 64)])
def test_round_trip_tight(encoding: str, channels: int, dtype: type, h: int, w: int) -> None:
    arr = sample(h, w, channels, dtype)
    msg = numpy_to_image(arr, encoding, Header(frame_id="camera"))
    itemsize = np.dtype(dtype).itemsize
    assert (msg.height, msg.width, msg.encoding, msg.step) == (h, w, encoding, w * channels * itemsize)
    assert msg.is_bigendian == 0 and isinstance(msg.data, bytes) and len(msg.data) == h * msg.step
    back = image_to_numpy(Image.deserialize(msg.serialize()))
    assert back.dtype == dtype and back.shape == arr.shape
    np.testing.assert_array_equal(back, arr)


@pytest.mark.parametrize(("encoding", "channels", "dtype"), ENCODINGS)
@pytest.mark.parametrize("pad", [1, 2, 7, 64])
def test_step_padding_is_skipped(encoding: str, channels: int, dtype: type, pad: int) -> None:
    h, w = 5, 7
    arr = sample(h, w, channels, dtype)
    row = w * channels * np.dtype(dtype).itemsize
    padded = np.full((h, row + pad), 0xAB, dtype=np.uint8)
    padded[:, :row] = np.frombuffer(arr.astype(np.dtype(dtype).newbyteorder("<")).tobytes(), np.uint8).reshape(h, row)
    msg = Image(height=h, width=w, encoding=encoding, step=row + pad, data=padded.tobytes())
    np.testing.assert_array_equal(image_to_numpy(msg), arr)


def test_odd_step_padding_for_mono16() -> None:
    arr = sample(4, 3, 1, np.uint16)
    padded = np.zeros((4, 7), np.uint8)
    padded[:, :6] = np.frombuffer(arr.astype("<u2").tobytes(), np.uint8).reshape(4, 6)
    msg = Image(height=4, width=3, encoding="mono16", step=7, data=padded.tobytes())
    np.testing.assert_array_equal(image_to_numpy(msg), arr)


def test_big_endian_mono16() -> None:
    arr = sample(4, 6, 1, np.uint16)
    msg = Image(height=4, width=6, encoding="mono16", is_bigendian=1, step=12, data=arr.astype(">u2").tobytes())
    out = image_to_numpy(msg)
    np.testing.assert_array_equal(out, arr)
    assert out.dtype == np.uint16


@pytest.mark.parametrize(("encoding", "channels", "dtype"), ENCODINGS)
def test_to_bgr(encoding: str, channels: int, dtype: type) -> None:
    arr = sample(4, 5, channels, dtype)
    bgr = to_bgr(numpy_to_image(arr, encoding))
    assert bgr.shape == (4, 5, 3) and bgr.dtype == np.uint8
    if encoding == "rgb8":
        np.testing.assert_array_equal(bgr, arr[:, :, ::-1])
    if encoding in ("bgra8", "bgr8"):
        np.testing.assert_array_equal(bgr, arr[:, :, :3])


def bad(**kw: object) -> Image:
    base = {"height": 2, "width": 2, "encoding": "bgr8", "step": 6, "data": bytes(12)}
    base.update(kw)
    return Image(**base)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("msg", "words"),
    [
        (bad(data=bytes(11)), ["len(Image.data)", "Image.height", "Image.step", "11", "12"]),
        (bad(data=bytes(13)), ["len(Image.data)", "13"]),
        (bad(encoding="yuv422_weird"), ["Image.encoding", "yuv422_weird"]),
        (bad(encoding=""), ["Image.encoding"]),
        (bad(step=5), ["Image.step", "5", "6"]),
        (bad(height=0, width=0, step=0, data=b""), ["Image.height", "Image.width", "0x0"]),
        (bad(height=2, width=0, step=0, data=b""), ["Image.width"]),
        (bad(height=20000, width=20000, step=60000, data=bytes(100)), ["Image.height", "Image.width", "20000"]),
    ],
)
def test_bad_images_raise_clear_value_errors(msg: Image, words: list[str]) -> None:
    with pytest.raises(ValueError) as info:
        image_to_numpy(msg)
    text = str(info.value)
    for word in words:
        assert word in text, f"{word!r} not in {text!r}"


@pytest.mark.parametrize(
    ("arr", "encoding", "words"),
    [
        (np.zeros((4, 4, 3), np.uint8), "mono8", ["shape", "mono8"]),
        (np.zeros((4, 4), np.uint8), "bgr8", ["shape", "bgr8"]),
        (np.zeros((4, 4, 4), np.uint8), "bgr8", ["shape", "3 channels"]),
        (np.zeros((4, 4, 3), np.float32), "bgr8", ["dtype", "float32"]),
        (np.zeros((4, 4), np.uint8), "mono16", ["dtype", "uint16"]),
        (np.zeros((4, 4, 3), np.uint8), "hsv8", ["encoding", "hsv8"]),
    ],
)
def test_bad_arrays_raise_clear_value_errors(arr: np.ndarray, encoding: str, words: list[str]) -> None:
    with pytest.raises(ValueError) as info:
        numpy_to_image(arr, encoding)
    for word in words:
        assert word in str(info.value)


def test_vga_frame_is_one_block_of_bytes() -> None:
    """A 640x480 bgr8 frame crosses serialize/deserialize as a single `bytes` block (cyclonedds'
    BytesMachine), not as 921600 Python ints."""
    Image.__idl__.populate()
    machines = Image.__idl__.v1_machine.members_machines
    assert type(machines["data"]).__name__ == "BytesMachine"
    arr = sample(480, 640, 3, np.uint8)
    msg = numpy_to_image(arr, "bgr8")
    raw = msg.serialize()
    assert len(raw) >= 640 * 480 * 3
    back = Image.deserialize(raw)
    assert isinstance(back.data, bytes)
    assert back == msg
    view = image_to_numpy(back)
    assert not view.flags.owndata  # a view on the received buffer, no copy
    np.testing.assert_array_equal(view, arr)
