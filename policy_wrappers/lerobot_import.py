"""Importing lerobot for one policy without importing every policy lerobot ships (start-up of ``indgen evaluate``).

``lerobot/policies/__init__.py`` (lerobot 0.6.1) imports the configuration of all ~20 policies, and several of those
subpackages import their models with them (EO1's transformers model, FastWAM's diffusers VAE, X-VLA's and GR00T's
processors): about a fifth of the time a tiny ACT takes to load. ``policy_package(type)`` imports only
``lerobot.policies.<type>`` (which registers its config with lerobot's ``PreTrainedConfig`` choice registry) under
a ``lerobot.policies`` package whose own ``__init__`` runs on the first attribute it is asked for that it lacks, so
``from lerobot.policies import SmolVLAConfig`` later in the process still works exactly as before.

Two modules on every policy's import path bind a name from an optional package they only use when called:
``lerobot.optim.schedulers`` binds diffusers' ``get_scheduler`` (training only) and
``lerobot.processor.tokenizer_processor`` binds transformers' ``AutoTokenizer``/``AutoProcessor`` (policies that
tokenize; transformers 5's ``AutoProcessor`` pulls ``modeling_utils`` and scipy.optimize). ``defer_optional_names()``
imports the two with lerobot's own "package not installed" branch, then binds each name to a ``Deferred`` that
imports the real object on first use and puts it in its place: an ACT loads without diffusers or transformers
(about 3 s of a 10 s start-up here), a policy that tokenizes gets the real ``AutoTokenizer`` when it builds its
processor.

Separately, transformers and diffusers each call ``importlib.metadata.packages_distributions()`` when imported (a
walk over every installed package's RECORD; 0.5-1.4 s on a 2-core machine); inside ``one_package_scan()`` the
second call gets a copy of the first's answer (nothing is installed or removed in between).
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata
import importlib.util
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

PACKAGE = "lerobot.policies"
_lock = threading.RLock()  # a package's __init__ may ask a name of another lazy package


def _lazy_package(name: str):
    """Package ``name`` with its ``__init__`` not run yet; it runs, once, on the first attribute lookup that
    misses (a name it exports, ``__all__``), never for a submodule import."""
    spec = importlib.util.find_spec(name)
    module = importlib.util.module_from_spec(spec)

    def __getattr__(attr: str):  # noqa: N807 (PEP 562 module hook)
        if attr.startswith("__") and attr != "__all__":
            raise AttributeError(attr)
        with _lock:
            if module.__dict__.pop("__getattr__", None) is not None:  # first miss: run the real __init__ now
                spec.loader.exec_module(module)
        return getattr(module, attr)

    module.__getattr__ = __getattr__
    return module


def _install() -> None:
    """``lerobot.policies`` and each of its subpackages as lazy packages (what the import system would set)."""
    package = sys.modules[PACKAGE] = _lazy_package(PACKAGE)
    sys.modules["lerobot"].policies = package
    for entry in sorted(Path(package.__path__[0]).iterdir()):
        name = f"{PACKAGE}.{entry.name}"
        if (entry / "__init__.py").is_file() and entry.name.isidentifier() and name not in sys.modules:
            sys.modules[name] = _lazy_package(name)  # e.g. lerobot.policies.groot: only the modules asked for
            setattr(package, entry.name, sys.modules[name])


def policy_package(policy_type: str | None) -> None:
    """Import ``lerobot.policies.<policy_type>`` (registering its config, as its ``__init__`` does) without the
    other policies: lerobot's ``factory`` imports GR00T's and EVO1's configuration modules but no longer their
    packages (GR00T's imports ``lerobot.datasets``). An unknown type (a plugin) or None imports all of
    ``lerobot.policies`` as usual."""
    with _lock:
        if PACKAGE not in sys.modules:
            _install()
            defer_optional_names()
    if policy_type and policy_type.isidentifier():
        try:
            module = importlib.import_module(f"{PACKAGE}.{policy_type}")
        except ModuleNotFoundError as e:
            if e.name != f"{PACKAGE}.{policy_type}":
                raise
        else:
            getattr(module, "__all__", None)  # its own __init__ runs now if it was still lazy
            return
    getattr(sys.modules[PACKAGE], "__all__", None)  # not one of lerobot's subpackages: the whole package


# module -> (lerobot.utils.import_utils flag its import reads, {name: package the name comes from})
DEFERRED = {
    "lerobot.optim.schedulers": ("_diffusers_available", {"get_scheduler": "diffusers.optimization"}),
    "lerobot.processor.tokenizer_processor": (
        "_transformers_available",
        {"AutoProcessor": "transformers", "AutoTokenizer": "transformers"},
    ),
}


class Deferred:
    """``source.name`` imported on first use (a call or an attribute), which also rebinds ``owner.name`` to it."""

    def __init__(self, owner: str, name: str, source: str) -> None:
        self._where = (owner, name, source)

    def resolve(self):
        owner, name, source = self._where
        real = getattr(importlib.import_module(source), name)
        if getattr(sys.modules[owner], name) is self:
            setattr(sys.modules[owner], name, real)
        return real

    def __call__(self, *args, **kwargs):
        return self.resolve()(*args, **kwargs)

    def __getattr__(self, attr: str):
        if attr.startswith("__"):
            raise AttributeError(attr)
        return getattr(self.resolve(), attr)

    def __repr__(self) -> str:
        owner, name, source = self._where
        return f"<deferred {source}.{name} in {owner}>"


def defer_optional_names() -> None:
    """Import the ``DEFERRED`` modules without their optional packages, binding ``Deferred`` names instead
    (nothing happens for a module already imported, or when a package is not installed: lerobot's own fallback)."""
    with _lock:
        todo = {m: v for m, v in DEFERRED.items() if m not in sys.modules}
        if not todo:
            return
        import lerobot.utils.import_utils as flags

        saved = {flag: getattr(flags, flag) for flag, _ in todo.values()}
        if not all(saved.values()):
            return
        try:
            for flag in saved:
                setattr(flags, flag, False)
            for module in todo:
                importlib.import_module(module)
        finally:
            for flag, value in saved.items():
                setattr(flags, flag, value)
        for module, (flag, names) in todo.items():
            owner = sys.modules[module]
            setattr(owner, flag, True)  # its call-time checks see the package as installed, as it is
            for name, source in names.items():
                if getattr(owner, name) is None:
                    setattr(owner, name, Deferred(module, name, source))


@contextlib.contextmanager
def one_package_scan() -> Iterator[None]:
    """Within this block ``importlib.metadata.packages_distributions()`` scans the installed packages once."""
    real = importlib.metadata.packages_distributions
    cache: list[dict[str, list[str]]] = []

    def packages_distributions() -> dict[str, list[str]]:
        if not cache:
            cache.append(real())
        return {name: list(dists) for name, dists in cache[0].items()}

    importlib.metadata.packages_distributions = packages_distributions
    try:
        yield
    finally:
        importlib.metadata.packages_distributions = real
