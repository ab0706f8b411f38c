"""``torch.save`` messages, the wire of RoboCasa365's GR00T N1.5 server, read back without running pickled code.

RoboCasa365's GR00T fork (robocasa-benchmark/Isaac-GR00T ``gr00t/eval/service.py`` ``TorchSerializer``, the N1.5
service before Isaac-GR00T moved to msgpack) frames every request and reply as ``torch.save(dict)`` bytes and reads
them with ``torch.load(weights_only=False)``. We write the same bytes and read replies with ``weights_only=True``,
allowing only numpy's array reconstruction, so a hostile server cannot run code here; its ``ModalityConfig`` objects
(gr00t classes) are therefore refused, and the caller treats that reply as declaring nothing.
"""

from __future__ import annotations

import io
from typing import Any

ZIP_MAGIC = b"PK\x03\x04"  # torch.save's archive format


def looks_like_torch(message: bytes) -> bool:
    """Whether ``message`` is a ``torch.save`` archive (what a TorchSerializer server answers)."""
    return message[:4] == ZIP_MAGIC


def _numpy_globals() -> list:
    """numpy's pickling entry points under both numpy 1 and numpy 2 names (the server's numpy may be either)."""
    import numpy as np

    core = np._core if hasattr(np, "_core") else np.core
    reconstruct, scalar = core.multiarray._reconstruct, core.multiarray.scalar
    out: list = [np.ndarray, np.dtype, type(np.dtype(np.float32)), type(np.dtype(np.uint8))]
    for module in ("numpy.core.multiarray", "numpy._core.multiarray"):
        out += [(reconstruct, f"{module}._reconstruct"), (scalar, f"{module}.scalar")]
    dtypes = getattr(np, "dtypes", None)
    if dtypes is not None:
        out += [getattr(dtypes, n) for n in dir(dtypes) if n.endswith("DType")]
    return out


def torch_packb(obj: Any) -> bytes:
    """``TorchSerializer.to_bytes``: ``torch.save`` of the message into bytes."""
    import torch

    buf = io.BytesIO()
    torch.save(obj, buf)
    return buf.getvalue()


def torch_unpackb(message: bytes) -> Any:
    """``TorchSerializer.from_bytes`` restricted to tensors, numpy arrays and plain containers."""
    import torch

    with torch.serialization.safe_globals(_numpy_globals()):
        return torch.load(io.BytesIO(message), weights_only=True)
