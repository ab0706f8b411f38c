"""Byte-level checks of the two msgpack array encodings against their upstream definitions."""

from __future__ import annotations

import io

import msgpack
import numpy as np
import pytest

from policy_wrappers import msgpack_numpy as mn


def test_openpi_ndarray_encoding_is_byte_identical():
    arr = np.arange(6, dtype=np.float32).reshape(2, 3)
    expected = msgpack.packb(
        {"a": {b"__ndarray__": True, b"data": arr.tobytes(), b"dtype": "<f4", b"shape": (2, 3)}}
    )
    assert mn.packb({"a": arr}) == expected
    assert mn.Packer().pack({"a": arr}) == expected


def test_openpi_scalar_and_roundtrip():
    msg = {"img": np.zeros((4, 4, 3), np.uint8), "s": np.float32(1.5), "i": np.int64(3), "p": "go"}
    expected_scalar = msgpack.packb({b"__npgeneric__": True, b"data": 1.5, b"dtype": "<f4"})
    assert mn.packb(np.float32(1.5)) == expected_scalar
    assert mn.packb(np.float64(1.5)) == msgpack.packb(
        1.5
    )  # a float subclass: msgpack packs it natively, as upstream
    out = mn.unpackb(mn.packb(msg))
    assert out["img"].dtype == np.uint8 and out["img"].shape == (4, 4, 3)
    assert isinstance(out["s"], np.float32) and out["s"] == 1.5 and isinstance(out["i"], np.int64)
    assert out["p"] == "go"


@pytest.mark.parametrize("bad", [np.array([object()]), np.array([1 + 2j])])
def test_openpi_refuses_object_and_complex(bad):
    with pytest.raises(ValueError, match="Unsupported dtype"):
        mn.packb(bad)


def test_groot_encoding_is_npy_inside_msgpack():
    arr = np.arange(4, dtype=np.float32).reshape(1, 4)
    raw = msgpack.unpackb(mn.groot_packb({"state.x": arr}))
    assert raw["state.x"]["__ndarray_class__"] is True
    assert np.array_equal(np.load(io.BytesIO(raw["state.x"]["as_npy"]), allow_pickle=False), arr)
    back = mn.groot_unpackb(mn.groot_packb({"a": [arr, {"b": arr}]}))
    assert np.array_equal(back["a"][1]["b"], arr)


def test_groot_modality_config_decodes_to_dict():
    n15 = msgpack.packb(
        {
            "video": {
                "__ModalityConfig_class__": True,
                "as_json": '{"delta_indices": [0], "modality_keys": ["video.image"]}',
            }
        }
    )
    n16 = msgpack.packb(
        {
            "video": {
                "__ModalityConfig_class__": True,
                "as_json": {"delta_indices": [0], "modality_keys": ["image"]},
            }
        }
    )
    assert mn.groot_unpackb(n15)["video"]["modality_keys"] == ["video.image"]
    assert mn.groot_unpackb(n16)["video"]["modality_keys"] == ["image"]
