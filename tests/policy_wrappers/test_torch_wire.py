"""The torch.save wire of RoboCasa365's GR00T N1.5 server (robocasa-benchmark/Isaac-GR00T ``gr00t/eval/service.py``
``TorchSerializer``, read from its copy XingxinHE/Isaac-GR00T 9d7d7a9eb7ad30bd8ce30448d9ab53a918b45b10): replies are
read back with their arrays intact, under numpy 1's and numpy 2's names, and nothing else is unpickled."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from policy_wrappers.torch_wire import looks_like_torch, torch_packb, torch_unpackb

torch = pytest.importorskip("torch")


def test_a_reply_of_arrays_round_trips():
    reply = {
        "action.gripper_close": np.ones((2, 16, 1), np.float32),
        "names": ("a", "b"),
        "t": torch.zeros(3),
    }
    raw = torch_packb(reply)
    assert looks_like_torch(raw) and not looks_like_torch(b"\x81\xa5error")
    back = torch_unpackb(raw)
    np.testing.assert_array_equal(back["action.gripper_close"], reply["action.gripper_close"])
    assert back["action.gripper_close"].dtype == np.float32 and back["names"] == ("a", "b")


def test_numpy_1_names_are_read():
    """A server on numpy 1 pickles arrays as ``numpy.core.multiarray._reconstruct``; numpy 2 as ``numpy._core``."""
    raw = torch_packb({"a": np.arange(3, dtype=np.float32)})
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(raw)) as zin, zipfile.ZipFile(out, "w", zipfile.ZIP_STORED) as zout:
        for info in zin.infolist():
            data = zin.read(info.filename)
            if info.filename.endswith("data.pkl"):
                data = data.replace(b"numpy._core.multiarray", b"numpy.core.multiarray")
            zout.writestr(info, data)
    np.testing.assert_array_equal(torch_unpackb(out.getvalue())["a"], [0, 1, 2])


class _Hostile:
    def __reduce__(self):
        import os

        return (os.system, ("touch should_not_exist",))


def test_a_pickled_callable_is_refused_not_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(Exception, match="(?i)weights only|unsupported global"):
        torch_unpackb(torch_packb({"x": _Hostile()}))
    assert not (tmp_path / "should_not_exist").exists()
