"""msgpack with numpy arrays, in the two wire formats our servers speak: openpi's and Isaac-GR00T's.

openpi (``openpi_client/msgpack_numpy.py``): ndarrays become ``{b"__ndarray__": True, b"data", b"dtype",
b"shape"}`` and numpy scalars ``{b"__npgeneric__": True, b"data", b"dtype"}``; object/void/complex refused.
GR00T (``gr00t/eval/service.py``): ndarrays become ``{"__ndarray_class__": True, "as_npy": <np.save bytes>}``.
"""

from __future__ import annotations

import io
from typing import Any

import msgpack
import numpy as np

_REFUSED_KINDS = ("V", "O", "c")


def _openpi_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray | np.generic) and obj.dtype.kind in _REFUSED_KINDS:
        raise ValueError(f"Unsupported dtype: {obj.dtype}")
    if isinstance(obj, np.ndarray):
        return {b"__ndarray__": True, b"data": obj.tobytes(), b"dtype": obj.dtype.str, b"shape": obj.shape}
    if isinstance(obj, np.generic):
        return {b"__npgeneric__": True, b"data": obj.item(), b"dtype": obj.dtype.str}
    return obj


def _openpi_hook(obj: dict) -> Any:
    if b"__ndarray__" in obj:
        return np.ndarray(buffer=obj[b"data"], dtype=np.dtype(obj[b"dtype"]), shape=obj[b"shape"])
    if b"__npgeneric__" in obj:
        return np.dtype(obj[b"dtype"]).type(obj[b"data"])
    return obj


def packb(obj: Any) -> bytes:
    """Serialise with openpi's array encoding."""
    return msgpack.packb(obj, default=_openpi_default)


def unpackb(data: bytes) -> Any:
    """Deserialise openpi's array encoding (arrays are read-only views on the message)."""
    return msgpack.unpackb(data, object_hook=_openpi_hook)


def Packer() -> msgpack.Packer:  # noqa: N802 - mirrors openpi_client.msgpack_numpy.Packer
    """A reusable packer with openpi's array encoding."""
    return msgpack.Packer(default=_openpi_default)


def _groot_default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        buf = io.BytesIO()
        np.save(buf, obj, allow_pickle=False)
        return {"__ndarray_class__": True, "as_npy": buf.getvalue()}
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _groot_hook(obj: Any) -> Any:
    if not isinstance(obj, dict):
        return obj
    if "__ndarray_class__" in obj:
        return np.load(io.BytesIO(obj["as_npy"]), allow_pickle=False)
    if "__ModalityConfig_class__" in obj:  # N1.5 sends a JSON string, N1.6 a dict
        raw = obj["as_json"]
        if isinstance(raw, str | bytes):
            import json

            raw = json.loads(raw)
        return dict(raw)
    return obj


def groot_packb(obj: Any) -> bytes:
    """Serialise with Isaac-GR00T's ``MsgSerializer`` encoding (npy bytes inside msgpack)."""
    return msgpack.packb(obj, default=_groot_default)


def groot_unpackb(data: bytes) -> Any:
    """Deserialise Isaac-GR00T's encoding; ModalityConfig objects come back as plain dicts."""
    return msgpack.unpackb(data, object_hook=_groot_hook)
