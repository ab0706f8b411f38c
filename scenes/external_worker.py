"""The worker side of a scene family that runs its simulator in its own Python environment (``scenes.external``).

Run by path with that environment's interpreter: ``python external_worker.py BACKEND.py``. It imports only the
standard library and numpy itself; ``BACKEND.py`` (e.g. ``scenes/robocasa/backend.py``) imports the simulator and
defines ``build(config: dict)`` returning an object with ``reset(seed) -> dict``, ``step(action) -> dict``,
``privileged() -> dict``, ``mj_data()`` and ``close()``, and ``versions() -> dict``.

Protocol: length-prefixed pickles on the original stdout/stdin (fd 1 is redirected to stderr so a library's prints
cannot corrupt a frame). Requests are ``(op, arg)``; replies ``("ok", value)``, ``("error", one_line)``, or
``("unavailable", one_line)`` for an exception whose ``unavailable`` attribute is true. After every
reset and step the worker reads MuJoCo's warning counters: a new ``mjWARN_BADQACC`` (MuJoCo reset mjData to qpos0
without raising) or any other new instability warning is an error reply, never a silently reset episode.
"""

from __future__ import annotations

import importlib.util
import os
import pickle
import struct
import sys
import traceback

# mjtWarning indices (mujoco/mjdata.h): the ones after which the state is no longer the policy's doing
UNSTABLE = {4: "mjWARN_BADQPOS", 5: "mjWARN_BADQVEL", 6: "mjWARN_BADQACC"}


def read_frame(stream) -> object | None:
    head = stream.read(4)
    if len(head) < 4:
        return None
    (n,) = struct.unpack("<I", head)
    return pickle.loads(stream.read(n))


def write_frame(stream, obj: object) -> None:
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(struct.pack("<I", len(data)) + data)
    stream.flush()


def describe(e: BaseException) -> str:
    """One line: type, first message line, where it was raised."""
    tb = traceback.extract_tb(e.__traceback__)
    where = f" at {os.path.basename(tb[-1].filename)}:{tb[-1].lineno}" if tb else ""
    msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
    return f"{type(e).__name__}: {msg}{where}"


class WarningWatch:
    """Counts of MuJoCo's instability warnings, compared after every reset and step."""

    def __init__(self):
        self.seen: dict[int, int] = {}

    def check(self, data, when: str) -> None:
        if data is None:
            return
        for idx, name in UNSTABLE.items():
            n = int(data.warning[idx].number)
            if n > self.seen.get(idx, 0):
                self.seen[idx] = n
                raise RuntimeError(
                    f"MuJoCo {name} after {when} (dof {int(data.warning[idx].lastinfo)}): the simulation went "
                    "unstable and MuJoCo reset it to qpos0"
                )

    def reset(self, data) -> None:
        self.seen = {i: int(data.warning[i].number) for i in UNSTABLE} if data is not None else {}


def serve(backend_path: str, inp, out) -> None:
    spec = importlib.util.spec_from_file_location("indgen_external_backend", backend_path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    env = None
    watch = WarningWatch()
    while True:
        msg = read_frame(inp)
        if msg is None:
            break
        op, arg = msg
        try:
            if op == "close":
                break
            if op == "versions":
                value = module.versions()
            elif op == "build":
                if env is not None:
                    env.close()
                    env = None
                env = module.build(arg)
                value = None
            elif op == "reset":
                watch.reset(
                    None
                )  # a reset builds fresh MjData: any instability warning since is this episode's
                value = env.reset(arg)
                watch.check(env.mj_data(), "reset")
            elif op == "step":
                value = env.step(arg)
                watch.check(env.mj_data(), "a step")
            elif op == "drop":  # the proxy keeps this worker idle: free the simulator, keep the interpreter
                if env is not None:
                    env.close()
                    env = None
                value = None
            elif op == "privileged":
                value = env.privileged()
            elif op == "call":  # a backend extra (e.g. ep_meta): (name, kwargs)
                name, kwargs = arg
                value = getattr(env, name)(**kwargs)
            elif op == "exit":  # tests: a worker that dies mid-episode
                os._exit(int(arg))
            else:
                raise ValueError(f"unknown op {op!r}")
            write_frame(out, ("ok", value))
        except Exception as e:  # "unavailable": the episode's seed rules the level out (never retried)
            write_frame(out, ("unavailable" if getattr(e, "unavailable", False) else "error", describe(e)))
    if env is not None:
        env.close()


def main() -> None:
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # anything printed goes to stderr, never into a frame
    sys.stdout = sys.stderr
    here = os.path.dirname(os.path.abspath(__file__))  # scenes/: its robocasa/ would shadow the real robocasa
    sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != here]
    serve(sys.argv[1], sys.stdin.buffer, out)


if __name__ == "__main__":
    main()
