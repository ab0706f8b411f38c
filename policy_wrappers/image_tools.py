"""Image conventions shared by the wrappers: 180° flip, openpi's resize-with-pad, OFT's resize, gripper maps."""

from __future__ import annotations

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


def resize_jpeg_lanczos(img: np.ndarray, height: int, width: int, quality: int = 95) -> np.ndarray:
    """OFT's ``resize_image_for_policy``: JPEG round trip then Lanczos resize (PIL stands in for tf.image)."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="JPEG", quality=quality)
    decoded = Image.open(io.BytesIO(buf.getvalue())).convert("RGB")
    if decoded.size != (width, height):
        decoded = decoded.resize((width, height), resample=Image.LANCZOS)
    return np.asarray(decoded)


GRIPPER_MODES = ("raw", "01", "01inv")


def convert_gripper(actions: np.ndarray, mode: str) -> np.ndarray:
    """Map a model's gripper output to ours (-1 open, +1 close).

    ``raw``: already ours. ``01``: [0, 1] -> [-1, 1] binarised (GR00T LIBERO). ``01inv``: the same, then
    sign-flipped, because OpenVLA's RLDS loader stores 0 = close (OpenVLA/OFT ``process_action``).
    """
    if mode == "raw":
        return actions
    out = np.array(actions, dtype=np.float32, copy=True)
    out[..., -1] = np.sign(2.0 * out[..., -1] - 1.0)
    if mode == "01inv":
        out[..., -1] *= -1.0
    return out
