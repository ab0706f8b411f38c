"""OpenVLA(-OFT)'s TF image preprocessing, checked against TF's formulas written out pixel by pixel."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from policy_wrappers.image_tools import jpeg_roundtrip_tf, resize_jpeg_lanczos, resize_lanczos3_tf


def tf_lanczos3_reference(img: np.ndarray, height: int, width: int) -> np.ndarray:
    """``tf.image.resize(method="lanczos3", antialias=True)`` (``scale_and_translate_op.cc``), then OpenVLA's
    ``tf.round`` + clip: per output sample ``s = (x + 0.5) / scale``, kernel widened by ``1 / scale`` when
    shrinking, taps ``ceil(s - 3k - 0.5) .. floor(s + 3k - 0.5)`` weighted by ``3 sin(pi t) sin(pi t / 3) /
    (pi t)^2`` at ``t = |i + 0.5 - s| / k`` and normalised to sum 1; rows first, then columns."""

    def weights(n_in: int, n_out: int) -> list[tuple[int, list[float]]]:
        inv = n_in / n_out
        k = max(inv, 1.0)
        out = []
        for x in range(n_out):
            s = (x + 0.5) * inv
            lo = min(max(math.ceil(s - 3 * k - 0.5), 0), n_in - 1)
            hi = min(max(math.floor(s + 3 * k - 0.5), 0), n_in - 1) + 1
            ts = [abs(i + 0.5 - s) / k for i in range(lo, hi)]
            w = [
                0.0
                if t > 3
                else 1.0
                if t <= 1e-3
                else 3 * math.sin(math.pi * t) * math.sin(math.pi * t / 3) / (math.pi * t) ** 2
                for t in ts
            ]
            out.append((lo, [v / sum(w) for v in w]))
        return out

    src = img.astype(np.float64)
    rows = np.stack(
        [sum(w * src[lo + j] for j, w in enumerate(ws)) for lo, ws in weights(img.shape[0], height)]
    )
    cols = np.stack(
        [sum(w * rows[:, lo + j] for j, w in enumerate(ws)) for lo, ws in weights(img.shape[1], width)],
        axis=1,
    )
    return np.clip(np.round(cols), 0, 255).astype(np.uint8)


@pytest.mark.parametrize(
    "shape, size", [((40, 40, 3), (35, 35)), ((23, 31, 3), (9, 40)), ((12, 12, 3), (12, 12))]
)
def test_lanczos3_matches_tf_formula(shape, size):
    img = np.random.default_rng(sum(shape)).integers(0, 256, shape, dtype=np.uint8)
    ours, ref = resize_lanczos3_tf(img, *size), tf_lanczos3_reference(img, *size)
    assert ours.shape == (*size, 3)
    # float32 vs float64: a value that lands on .5 may round the other way; nothing may be off by more than 1
    assert np.abs(ours.astype(int) - ref).max() <= 1 and (ours == ref).mean() > 0.995


def test_jpeg_roundtrip_is_tf_decode_not_pillows():
    """TF decodes with the fast integer IDCT; Pillow's default (the slow one) gives other pixels."""
    from PIL import Image

    yy, xx = np.mgrid[0:64, 0:64]
    img = np.stack([xx * 3, 128 + 100 * np.sin(xx / 5.0 + yy / 7.0), yy * 4], -1).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="JPEG", quality=95)
    pillow = np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGB"))
    ours = jpeg_roundtrip_tf(img)
    assert ours.shape == img.shape and ours.dtype == np.uint8
    assert not np.array_equal(ours, pillow) and np.abs(ours.astype(int) - pillow).max() < 40
    assert np.abs(ours.astype(int) - img).mean() < 3  # still a quality-95 copy of the input


def test_resize_jpeg_lanczos_resizes_even_at_the_target_size():
    img = np.random.default_rng(1).integers(0, 256, (24, 24, 3), dtype=np.uint8)
    assert np.array_equal(
        resize_jpeg_lanczos(img, 24, 24), resize_lanczos3_tf(jpeg_roundtrip_tf(img), 24, 24)
    )
    assert resize_jpeg_lanczos(img, 16, 16).shape == (16, 16, 3)
