"""Importing lerobot for one policy without importing every policy lerobot ships (start-up of ``indgen evaluate``).

``lerobot/policies/__init__.py`` (lerobot 0.6.1) imports the configuration of all ~20 policies, and several of those
subpackages import their models with them (EO1's transformers model, FastWAM's diffusers VAE, X-VLA's and GR00T's
processors): about a fifth of the time a tiny ACT takes to load. ``policy_package(type)`` imports only
``lerobot.policies.<type>`` (which registers its config with lerobot's ``PreTrainedConfig`` choice registry) under
a ``lerobot.policies`` package whose own ``__init__`` runs on the first attribute it is asked for that it lacks, so
``from lerobot.policies import SmolVLAConfig`` later in the process still works exactly as before.

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
