"""Commands as nested frozen configs: a field's ``option`` metadata is its flag, its API keyword and its preset key,
so a command's parser, its Python API and its YAML are made from one definition and never drift apart.

A config is a frozen dataclass whose fields are options or sections (fields whose type is itself such a dataclass,
given a ``default_factory``); options have flat names, unique across the sections (``flat_options``)."""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import numbers
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from indgen_vla.core.errors import ConfigError


def option(default: Any = dataclasses.MISSING, help: str | None = None, *, name: str | None = None,
           flag: str | None = None, **argparse_kwargs: Any) -> Any:  # fmt: skip
    """A config field and its option: ``help`` its --help line (``None``: no flag, API and YAML only), ``name`` its
    flat name where it differs from the field's, ``flag`` its flag's name where it differs from ``name``;
    ``argparse_kwargs`` (type, choices, metavar, default_factory aside) go to ``add_argument`` as they are."""
    meta = {"help": help, "name": name, "flag": flag, "argparse": argparse_kwargs}
    return field(default=default, metadata=meta)


def option_like(cls: type, name: str, default: Any = dataclasses.MISSING, help: Any = dataclasses.MISSING,
                **argparse_kwargs: Any) -> Any:  # fmt: skip
    """Another config's option ``name`` (its flat name, flag, help line, argparse keywords and default) for a command
    where the idea is the same, so both keep one name and one definition; ``default``, ``help`` and argparse
    keywords given replace its own."""
    o = flat_options(cls)[name]
    meta = o.field.metadata
    return option(
        o.field.default if default is dataclasses.MISSING else default,
        meta["help"] if help is dataclasses.MISSING else help,
        name=meta["name"], flag=meta["flag"], **{**meta["argparse"], **argparse_kwargs},
    )  # fmt: skip


def check_types(config: Any) -> None:
    """One ``ConfigError`` line for an option whose value has the wrong type (the Python API and YAML hand values
    argparse never parsed); NumPy scalars become Python ones, so manifests stay JSON (``typed_value``)."""
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        typed = typed_value(f, value)
        if typed is not value:
            object.__setattr__(config, f.name, typed)


def typed_value(f: dataclasses.Field, value: Any) -> Any:
    """``value`` as the option ``f`` takes it: a whole number where the flag parses ``int`` (or the default is one),
    a number where it parses ``float``, true/false for a switch; anything else is one ``ConfigError`` line naming
    the flag and, where there is one, an example from its default."""
    meta = f.metadata.get("argparse")
    if meta is None or value is None:
        return value
    kind = meta.get("type") if "type" in meta else type(f.default)
    if kind not in (bool, int, float) or "choices" in meta:
        return value
    boolean = isinstance(value, bool) or (
        type(value).__module__ == "numpy" and type(value).__name__ in ("bool", "bool_")
    )
    if kind is bool and boolean:
        return value if isinstance(value, bool) else bool(value)
    if kind is int and not boolean and isinstance(value, numbers.Integral):
        return value if type(value) is int else int(value)
    if kind is float and not boolean and isinstance(value, numbers.Real):
        return value if isinstance(value, int | float) else float(value)
    what = {bool: "true or false", int: "a whole number", float: "a number"}[kind]
    flag = f.metadata.get("flag") or f.metadata.get("name") or f.name
    name = f"--{flag.replace('_', '-')}" if f.metadata.get("help") else flag
    example = (
        ""
        if kind is bool or f.default is None or f.default is dataclasses.MISSING
        else f"; e.g. {name} {f.default}"
        if name.startswith("--")
        else f"; e.g. {name}={f.default}"
    )
    raise ConfigError(f"{name} must be {what}, got {value!r} ({type(value).__name__}){example}")


def section(cls: type) -> Any:
    """A config field holding a whole section (a nested config), defaulting to that section's defaults."""
    return field(default_factory=cls, metadata={"section": True})


@dataclass(frozen=True)
class Option:
    """One option: its flat name, the path of sections that holds it, and its field there."""

    name: str
    path: tuple[str, ...]
    field: dataclasses.Field

    @property
    def flag(self) -> str | None:
        """The flag's name with ``_`` (argparse's dest), or ``None`` when the option has no flag."""
        if self.field.metadata.get("help") is None:
            return None
        return self.field.metadata.get("flag") or self.name

    @property
    def negatable(self) -> bool:
        """A ``--no-...`` flag: its False overrides a preset (other False flags are "not given")."""
        return self.field.metadata["argparse"].get("action") is argparse.BooleanOptionalAction

    @property
    def section(self) -> str:
        """The top-level section holding the option ("" for a field of the config itself)."""
        return self.path[0] if self.path else ""


def _section_types(cls: type) -> dict[str, type]:
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls) if f.metadata.get("section")}


def flat_options(cls: type) -> dict[str, Option]:
    """Every option of a config class and its sections, by flat name; two options sharing a name is a bug."""
    sections = _section_types(cls)
    out: dict[str, Option] = {}
    for f in dataclasses.fields(cls):
        found = (
            {
                n: dataclasses.replace(o, path=(f.name, *o.path))
                for n, o in flat_options(sections[f.name]).items()
            }
            if f.name in sections
            else {f.metadata.get("name") or f.name: Option(f.metadata.get("name") or f.name, (), f)}
        )
        for n, o in found.items():
            if n in out:
                raise TypeError(f"{cls.__name__}: option {n!r} is defined twice")
            out[n] = o
    return out


def from_flat(cls: type, values: Mapping[str, Any], *, command: str) -> Any:
    """A config from flat option names, the defaults for the rest; an unknown name is one clear error naming
    ``command``'s options."""
    options = flat_options(cls)
    unknown = sorted(set(values) - set(options))
    if unknown:
        raise ConfigError(
            f"unknown option(s) {', '.join(unknown)} for {command}; see 'indgen {command} --help'"
        )
    return _build(cls, dict(values), options, ())


def _build(cls: type, values: dict[str, Any], options: dict[str, Option], path: tuple[str, ...]) -> Any:
    sections = _section_types(cls)
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if f.name in sections:
            kwargs[f.name] = _build(sections[f.name], values, options, (*path, f.name))
            continue
        name = f.metadata.get("name") or f.name
        if name in values and options[name].path == path:
            kwargs[f.name] = values[name]
    return cls(**kwargs)


def to_flat(config: Any) -> dict[str, Any]:
    """Every option of a config under its flat name (what a manifest records, what ``from_flat`` reads back)."""
    out: dict[str, Any] = {}
    for name, o in flat_options(type(config)).items():
        value = config
        for part in (*o.path, o.field.name):
            value = getattr(value, part)
        out[name] = value
    return out


def add_flags(
    parser: argparse.ArgumentParser,
    cls: type,
    names: Iterable[str] | None = None,
    *,
    skip: Iterable[str] = (),
) -> None:
    """Add a config's flags (all of them, or ``names``) to a parser, each from its field's metadata; a bool is a
    switch, and a flag left out parses as ``None`` so that the config's default (or a preset) applies."""
    options = flat_options(cls)
    wanted = list(options) if names is None else list(names)
    for name in wanted:
        o = options[name]
        if name in skip or (o.flag is None and names is None):
            continue
        add_option_flag(parser, o)


def add_option_flag(parser: argparse.ArgumentParser, o: Option, help: str | None = None) -> None:
    """One option's flag from its field's metadata (``help`` replaces its help line): its type, choices and metavar;
    a bool is a switch; a flag left out parses as ``None`` so that the config's default (or a preset) applies."""
    if o.flag is None:
        raise ValueError(f"option {o.name} has no flag (its field's metadata has no help line)")
    kwargs = dict(o.field.metadata["argparse"])
    if isinstance(o.field.default, bool) and "action" not in kwargs:
        kwargs["action"] = "store_true"
    else:
        kwargs.setdefault("default", None)
    parser.add_argument(
        "--" + o.flag.replace("_", "-"), dest=o.flag, help=help or o.field.metadata["help"], **kwargs
    )


def from_args(
    cls: type,
    args: argparse.Namespace | Mapping[str, Any],
    /,
    *,
    command: str,
    base: Any = None,
    **fixed: Any,
) -> Any:
    """A config from parsed flags, or from the API's keyword arguments named like them (a mapping: a name that is
    no option is refused, and a False given is a value): every value given wins over ``base``'s (a config of
    ``cls``; None: the defaults); ``fixed`` values (positional arguments, what the command adds) are set as they are."""
    strict = not isinstance(args, argparse.Namespace)
    given = dict(args) if strict else vars(args)
    options = flat_options(cls)
    by_flag = {o.flag: n for n, o in options.items() if o.flag}
    values: dict[str, Any] = {} if base is None else to_flat(base)
    for key, value in given.items():
        name = by_flag.get(key, key if key in options else None)
        if name is None:
            if strict:
                close = difflib.get_close_matches(key, [*options, *by_flag], n=1)
                hint = f"; did you mean {close[0]!r}?" if close else f"; see 'indgen {command} --help'"
                raise ConfigError(f"unknown option {key!r} for {command}{hint}")
            continue
        if value is None or (value is False and not strict and not options[name].negatable):
            continue
        values[name] = value
    values.update(fixed)
    return from_flat(cls, values, command=command)
