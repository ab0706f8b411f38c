"""What every ``indgen`` parser shares: one-line errors with a suggestion, negative level ranges as values, the
level options (evaluate, certify, preview, demos) and the passthrough subcommands that parse their own arguments."""

from __future__ import annotations

import argparse
import re
from collections.abc import Iterable

from indgen_vla.app.config_fields import add_option_flag
from indgen_vla.app.engine.config import OPTIONS


class IndgenParser(argparse.ArgumentParser):
    """argparse that suggests the closest subcommand or choice on a typo, in one line, and reads
    level ranges such as ``--levels -3:3`` or ``--levels -2,0,2`` as values, not as options."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # no flag starts with a digit: -3:3, -3..3 are values
        self._negative_number_matcher = re.compile(r"^-\d")

    def error(self, message: str) -> None:  # type: ignore[override]
        import difflib

        m = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if m:
            choices = re.findall(r"'([^']*)'", m.group(2)) or [c.strip() for c in m.group(2).split(",")]
            close = difflib.get_close_matches(m.group(1), choices, n=1, cutoff=0.5)
            if close:
                message += f"; did you mean {close[0]!r}?"
        self.exit(2, f"{self.prog}: error: {message}\n")


LEVELS_DEFAULT = "default: the axis range"  # what an omitted --levels means to evaluate


def add_config_flags(
    p: argparse.ArgumentParser, names: Iterable[str], levels_default: str = LEVELS_DEFAULT
) -> None:
    """Add the flags of these evaluate options (flat names), each made from its config field's metadata
    (``indgen_vla.app.engine.config.option``): its help line, type, choices, metavar; a bool is a switch."""
    for name in names:
        o = OPTIONS[name]
        add_option_flag(
            p, o, (o.field.metadata["help"] or "").replace("{levels_default}", levels_default) or None
        )


def add_level_options(p: argparse.ArgumentParser, levels_default: str = LEVELS_DEFAULT) -> None:
    """--levels, --step and --axes-preset: which levels run and how far apart (evaluate, certify, preview and demos
    alike; ``levels_default`` says what an omitted --levels means there)."""
    add_config_flags(p, ("levels", "step", "axes_preset"), levels_default)


def add_scene_options(p: argparse.ArgumentParser) -> None:
    """--split and --obj-registries: RoboCasa365's split and object registries (evaluate's, certify's, preview's)."""
    add_config_flags(p, ("split", "obj_registries"))


def add_passthrough(sp: argparse._SubParsersAction, name: str, help_: str) -> None:
    """A subcommand whose handler parses the rest of the command line itself (``args.rest``)."""
    sp.add_parser(name, help=help_, add_help=False)
