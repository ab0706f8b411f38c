"""Image conventions shared by the wrappers: 180° flip, openpi's resize-with-pad, OFT's resize, gripper maps."""

from __future__ import annotations

import functools
import io

import numpy as np


def flip_180(img: np.ndarray) -> np.ndarray:
    """Rotate an HxWx3 image by 180° (LIBERO-trained checkpoints see the simulator upside down)."""
    return np.ascontiguousarray(img[::-1, ::-1])


def resize_with_pad(img: np.ndarray, height: int, width: int) -> np.ndarray:
    """openpi's ``image_tools.resize_with_pad`` for one uint8 image: keep aspect, bilinear, zero-pad centred."""
    from PIL import Image

    cur_h, cur_w = img.shape[:2]
    if (cur_h, cur_w) == (height, width):
        return img
    ratio = max(cur_w / width, cur_h / height)
    new_h, new_w = int(cur_h / ratio), int(cur_w / ratio)
    resized = Image.fromarray(img).resize((new_w, new_h), resample=Image.BILINEAR)
    canvas = Image.new(resized.mode, (width, height), 0)
    canvas.paste(resized, (max(0, int((width - new_w) / 2)), max(0, int((height - new_h) / 2))))
    return np.asarray(canvas)


def jpeg_roundtrip_tf(img: np.ndarray, quality: int = 95) -> np.ndarray:
    """``tf.io.decode_image(tf.image.encode_jpeg(img))`` as the RLDS builders and OpenVLA's evals run it.

    Pillow's quality-95 4:2:0 encoding decodes to the same pixels as TF's encoder; TF decodes with libjpeg's
    fast integer IDCT and fancy upsampling, which simplejpeg (libjpeg-turbo) exposes and Pillow does not.
    """
    import simplejpeg
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(img)).save(buf, format="JPEG", quality=quality)
    return simplejpeg.decode_jpeg(buf.getvalue(), colorspace="RGB", fastdct=True, fastupsample=False)


@functools.cache
def _lanczos3_spans(n_in: int, n_out: int) -> tuple[np.ndarray, np.ndarray]:
    """Per output index: first input index and normalised weights (TF ``scale_and_translate_op.cc``)."""
    f32, radius, pi = np.float32, np.float32(3.0), np.float32(3.14159265359)
    inv_scale = f32(1.0) / (f32(n_out) / f32(n_in))
    kscale = max(inv_scale, f32(1.0))  # antialias: widen the kernel when downsampling
    span = min(2 * int(np.ceil(radius * kscale)) + 1, n_in)
    starts, weights = np.zeros(n_out, np.int64), np.zeros((n_out, span), np.float32)
    for x in range(n_out):
        sample = (f32(x) + f32(0.5)) * inv_scale
        lo = min(max(int(np.ceil(sample - radius * kscale - f32(0.5))), 0), n_in - 1)
        hi = min(max(int(np.floor(sample + radius * kscale - f32(0.5))), 0), n_in - 1) + 1
        pos = np.abs((np.arange(lo, hi, dtype=np.float32) + f32(0.5) - sample) * (f32(1.0) / kscale))
        with np.errstate(divide="ignore", invalid="ignore"):
            w = radius * np.sin(pi * pos) * np.sin(pi * pos / radius) / (pi * pi * pos * pos)
        w = np.where(pos > radius, f32(0), np.where(pos <= f32(1e-3), f32(1), w)).astype(np.float32)
        total = np.float32(0)
        for v in w:  # the kernel sums in order
            total = np.float32(total + v)
        starts[x], weights[x, : hi - lo] = lo, w * (f32(1.0) / total)
    return starts, weights


def resize_lanczos3_tf(img: np.ndarray, height: int, width: int) -> np.ndarray:
    """``tf.image.resize(img, (height, width), "lanczos3", antialias=True)``, rounded (half to even) and
    clipped to uint8 as OpenVLA's ``resize_image``: float32, rows first, each span summed in order."""
    src = img.astype(np.float32)
    for axis, n_out in ((0, height), (1, width)):  # rows first, as TF
        n_in = src.shape[axis]
        starts, weights = _lanczos3_spans(n_in, n_out)
        moved = np.moveaxis(src, axis, 0)
        out = np.zeros((n_out, *moved.shape[1:]), np.float32)
        for k in range(weights.shape[1]):
            idx = np.minimum(starts + k, n_in - 1)
            w = np.where(starts + k < n_in, weights[:, k], np.float32(0)).astype(np.float32)
            out += w.reshape(-1, *([1] * (moved.ndim - 1))) * moved[idx]
        src = np.moveaxis(out, 0, axis)
    return np.clip(np.round(src), 0, 255).astype(np.uint8)


def resize_jpeg_lanczos(img: np.ndarray, height: int, width: int, quality: int = 95) -> np.ndarray:
    """OpenVLA/OFT's ``resize_image`` / ``resize_image_for_policy``: JPEG round trip, then Lanczos-3 resize."""
    return resize_lanczos3_tf(jpeg_roundtrip_tf(img, quality), height, width)  # TF resizes even at 224


GRIPPER_MODES = ("raw", "01", "01inv")


def convert_gripper(actions: np.ndarray, mode: str) -> np.ndarray:
    """Map a model's gripper output to ours (-1 open, +1 close).

    ``raw``: already ours. ``01``: [0, 1] -> [-1, 1] binarised, for a model whose 1 means close. ``01inv``:
    the same, then sign-flipped, because the RLDS loaders store 1 = open, 0 = close: OpenVLA/OFT's
    ``process_action`` and GR00T's LIBERO evals (N1.5 ``sign(1 - 2x)``, N1.6 ``-sign(2x - 1)``) all do this.
    """
    if mode == "raw":
        return actions
    out = np.array(actions, dtype=np.float32, copy=True)
    out[..., -1] = np.sign(2.0 * out[..., -1] - 1.0)
    if mode == "01inv":
        out[..., -1] *= -1.0
    return out


def center_crop_tf(img: np.ndarray, crop_scale: float = 0.9) -> np.ndarray:
    """OpenVLA's LIBERO ``center_crop`` (``openvla_utils.py:crop_and_resize``): keep the centred box of
    ``crop_scale`` of the area (side ``sqrt(crop_scale)``), resize it back to the input size.

    Reproduces ``tf.image.convert_image_dtype`` (uint8 * 1/255), ``tf.image.crop_and_resize`` (bilinear,
    corner-aligned sampling over the box) and the saturating cast back (``trunc(x * 255.5)``) in float32.
    """
    if not 0.0 < crop_scale <= 1.0:
        raise ValueError(f"crop_scale must be in (0, 1], got {crop_scale}")
    h, w = img.shape[:2]
    side = np.clip(np.sqrt(np.float32(crop_scale)), 0, 1).astype(np.float32)
    lo = (np.float32(1) - side) / np.float32(2)
    hi = lo + side
    src = img.astype(np.float32) * np.float32(1.0 / 255.0)

    def coords(n_in: int, n_out: int):  # crop_and_resize_op.cc: in_y = y1 * (H - 1) + y * height_scale
        scale = (hi - lo) * np.float32(n_in - 1) / np.float32(n_out - 1)
        pos = lo * np.float32(n_in - 1) + np.arange(n_out, dtype=np.float32) * scale
        low = np.floor(pos).astype(np.int64)
        return low, np.ceil(pos).astype(np.int64), (pos - low.astype(np.float32))

    top, bottom, ylerp = coords(h, h)  # the crop is resized back to the input size
    left, right, xlerp = coords(w, w)
    xl = xlerp[None, :, None]
    rows_top, rows_bottom = src[top], src[bottom]
    upper = rows_top[:, left] + (rows_top[:, right] - rows_top[:, left]) * xl
    lower = rows_bottom[:, left] + (rows_bottom[:, right] - rows_bottom[:, left]) * xl
    out = upper + (lower - upper) * ylerp[:, None, None]
    out = np.clip(out, 0, 1) * np.float32(255.5)
    return np.minimum(out, 255).astype(np.uint8)
