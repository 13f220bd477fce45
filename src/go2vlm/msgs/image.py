"""numpy <-> sensor_msgs/Image conversion without cv_bridge.

Bad input (unknown encoding, a data length that does not match height x step, a step shorter than a
row) raises `ValueError` naming the fields, never a reshape error deep inside numpy.
"""

from __future__ import annotations

import numpy as np

from go2vlm.geometry.camera import PinholeCamera
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
from go2vlm.msgs.std_msgs import Header

# encoding -> (channels, dtype)
ENCODINGS: dict[str, tuple[int, np.dtype]] = {
    "bgr8": (3, np.dtype(np.uint8)),
    "rgb8": (3, np.dtype(np.uint8)),
    "mono8": (1, np.dtype(np.uint8)),
    "8UC1": (1, np.dtype(np.uint8)),
    "8UC3": (3, np.dtype(np.uint8)),
    "bgra8": (4, np.dtype(np.uint8)),
    "rgba8": (4, np.dtype(np.uint8)),
    "mono16": (1, np.dtype(np.uint16)),
    "16UC1": (1, np.dtype(np.uint16)),
}

# Refuse absurd headers before allocating anything (a 20000x20000 header with little data).
MAX_PIXELS = 8192 * 8192


def image_to_numpy(msg: Image) -> np.ndarray:
    """View an Image as an (H, W) or (H, W, C) array; zero-copy where the row padding allows."""
    enc = msg.encoding
    if enc not in ENCODINGS:
        raise ValueError(f"Image.encoding {enc!r} is not supported; use one of {sorted(ENCODINGS)}")
    channels, dtype = ENCODINGS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if h <= 0 or w <= 0:
        raise ValueError(f"Image.height x Image.width is {h}x{w}; both must be positive")
    if h * w > MAX_PIXELS:
        raise ValueError(f"Image.height x Image.width = {h}x{w} exceeds the {MAX_PIXELS}-pixel limit")
    row = w * channels * dtype.itemsize
    if step < row:
        raise ValueError(f"Image.step {step} is shorter than Image.width x {channels * dtype.itemsize} = {row}")
    data = msg.data
    if len(data) != h * step:
        raise ValueError(
            f"len(Image.data) = {len(data)} does not match Image.height x Image.step = {h} x {step} = {h * step}"
        )
    buf = np.frombuffer(data, dtype=np.uint8).reshape(h, step)[:, :row]
    arr = buf.view(dtype.newbyteorder(">" if msg.is_bigendian else "<")) if dtype.itemsize > 1 else buf
    arr = arr.reshape(h, w, channels) if channels > 1 else arr.reshape(h, w)
    if dtype.itemsize > 1:
        arr = arr.astype(dtype, copy=False)
    return arr


def numpy_to_image(arr: np.ndarray, encoding: str = "bgr8", header: Header | None = None) -> Image:
    """Pack a uint8/uint16 array into an Image with a tight step."""
    if encoding not in ENCODINGS:
        raise ValueError(f"encoding {encoding!r} is not supported; use one of {sorted(ENCODINGS)}")
    channels, dtype = ENCODINGS[encoding]
    arr = np.asarray(arr)
    expect_ndim = 2 if channels == 1 else 3
    if arr.ndim == 3 and channels == 1 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim != expect_ndim or (channels > 1 and arr.shape[2] != channels):
        raise ValueError(f"array shape {arr.shape} does not fit encoding {encoding!r} ({channels} channels)")
    if arr.dtype != dtype:
        raise ValueError(f"array dtype {arr.dtype} does not fit encoding {encoding!r} ({dtype})")
    h, w = arr.shape[:2]
    arr = np.ascontiguousarray(arr, dtype=dtype.newbyteorder("<"))
    return Image(
        header=header or Header(),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=0,
        step=w * channels * dtype.itemsize,
        data=arr.tobytes(),
    )


def to_bgr(msg: Image) -> np.ndarray:
    """Any supported encoding as an (H, W, 3) uint8 BGR array (what OpenCV code expects)."""
    import cv2

    arr = image_to_numpy(msg)
    enc = msg.encoding
    if enc in ("bgr8", "8UC3"):
        return arr
    if enc == "rgb8":
        return cv2.cvtColor(arr, cv2.COLOR_RGB2BGR)
    if enc == "bgra8":
        return cv2.cvtColor(arr, cv2.COLOR_BGRA2BGR)
    if enc == "rgba8":
        return cv2.cvtColor(arr, cv2.COLOR_RGBA2BGR)
    if arr.dtype == np.uint16:
        arr = (arr >> 8).astype(np.uint8)
    return cv2.cvtColor(arr, cv2.COLOR_GRAY2BGR)


def camera_info(camera: PinholeCamera, header: Header | None = None) -> CameraInfo:
    """A CameraInfo for this pinhole camera, without distortion."""
    fx, fy, cx, cy = camera.fx, camera.fy, camera.cx, camera.cy
    return CameraInfo(
        header=header or Header(),
        height=camera.height,
        width=camera.width,
        distortion_model="plumb_bob",
        d=[0.0] * 5,
        k=camera.k,
        r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p=[fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
    )


def camera_model(info: CameraInfo) -> PinholeCamera:
    """The pinhole model of a CameraInfo; ValueError if its K is unusable."""
    return PinholeCamera.from_k(int(info.width), int(info.height), list(info.k))
